; MillFW demo job for the virtual machine (tools/run with no argument).
; Home, pick T1 and calibrate the tool setter with it, cut a pocket with arcs,
; change to T2 and measure it, drill a pattern, put the tool back (T0).
; +Z is up (RS274/NGC): machine Z 0 is the top switch, the work is below it
; at negative Z, and work Z is the tool tip.
G28                      ; home Z, Y, X
G21 G90 G17              ; mm, absolute, XY plane
T1 M6                    ; condition 1: pick tool 1 into the empty spindle
G37 L19.5 R0.75          ; calibrate the setter with T1 (19.5 mm long, 1.5 mm across)
M3 S8000
G0 X25 Y20
G0 Z-30                  ; tip 10 mm above the work
G1 Z-40 F300             ; plunge
G1 X27 F900
G2 X27 Y20 I-2 J0        ; full circle, radius 2
G1 X29
G2 X29 Y20 I-4 J0        ; full circle, radius 4
G1 X18 Y12
G1 X34                   ; rounded rectangle, corner radius 2
G3 X36 Y14 R2
G1 Y26
G3 X34 Y28 R2
G1 X18
G3 X16 Y26 R2
G1 Y14
G3 X18 Y12 R2
G0 Z-30
M5
T2 M6                    ; condition 2: tool 1 back to its pocket, pick tool 2
G37 D1                   ; measure tool 2: length and diameter
M3 S9000
G0 X12 Y34
G1 Z-42 F200             ; drill
G0 Z-30
G0 X20
G1 Z-42
G0 Z-30
G0 X28
G1 Z-42
G0 Z-30
G0 X28 Y40
G1 Z-42
G0 Z-30
G0 X20
G1 Z-42
G0 Z-30
G0 X12
G1 Z-42
G0 Z-30
M5
T0 M6                    ; condition 3: tool 2 back, spindle empty
G0 X5 Y5
M30                      ; program end
