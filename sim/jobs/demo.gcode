; Demo job for the virtual machine: only G-code the firmware supports early.
G28                ; home Z, Y, X (the homing lock refuses motion until then)
G21 G90            ; mm, absolute
G1 X10 Y10 F1200   ; feed to (10, 10)
G1 X20             ; feed along X
G0 X0 Y0           ; rapid home corner
M114               ; report position
