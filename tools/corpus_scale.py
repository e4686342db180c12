#!/usr/bin/env python3
"""Corpus jobs for the acceptance test of issue 13 (tests/corpus.rs).

Two things, both pure Python (stdlib only), sharing no code with the firmware:

* ``scale``: rewrite a third-party G-code file into the machine's work
  envelope. Only the numbers of coordinate words change (X Y Z I J K R, and
  R/Q of canned cycles); every other character of every line is kept, and one
  ``G28`` line is put in front. Nothing is mirrored: every coordinate becomes
  ``s * v + t`` with one uniform factor ``s > 0`` for X, Y and Z (so arcs stay
  circles in every plane, G18/G19 included) and a translation per axis.
* ``path``: an independent reference interpreter (RS274/NGC as LinuxCNC reads
  it) that turns a job into the commanded tool path as a polyline in MACHINE
  coordinates (mm): lines, arcs in G17/G18/G19 (helical too, full circles),
  G90/G91, G90.1/G91.1, G20/G21, G92, G53, G28 (homing, as this firmware
  means it), canned cycles G81/G82/G83/G73/G85/G89 (LinuxCNC semantics, G17),
  tool changes (marked, the harness skips the changer's own moves).

Scaling choices (also in README "Real jobs (corpus)"):
* One uniform factor for X, Y and Z, never above 1 (a job that fits is only
  moved). A separate Z factor would break G18/G19 arcs (Fusion's lead-ins in
  05 are G19 arcs), so there is none.
* G20 files stay in inches: the factor applies to the numbers as written and
  the translation is converted to inches, so the firmware's G20 is exercised.
* G91 coordinates, incremental arc centres (G91.1, the default) and R words
  are lengths: they are only scaled. G90.1 absolute centres and canned-cycle R
  in G90 are positions: scaled and translated. G53 lines (machine
  coordinates) are left as they are. F is left as it is (the CAM's feed).
* The region (machine mm): X 3..42, Y 3..25 (clear of the changer's station
  at X1 23, Y 28..44), Z 4..38 mm below the top switch (above the station's
  Z1 40.5). X and Y are centred in it; the job's highest point goes 4 mm below
  the top when the firmware is +Z up, and its lowest 4 mm below the top when
  the firmware still counts Z downward (``--z-down``; the numbers then land
  in 4..38 and the firmware runs the job upside down, see FIRMWARE_Z_UP in
  tests/corpus.rs).

Usage:
  corpus_scale.py scale IN OUT [--z-down]      prints the parameters as JSON
  corpus_scale.py path JOB OUT --start X,Y,Z [--z-down] [--g80-cancels] [--radii JSON]
                        (--radii: tool number -> radius, mm, for G41/G42)
  corpus_scale.py selftest                     checks of the model itself
Path file: ``L <job line>`` before the points of that line, ``P x y z s``
(machine mm, +Z up unless --z-down; s = 1: no Z word since the last tool
change, so Z is wherever the changer left it), ``J`` (a tool change may
happen here),
``U <line> <reason>`` (the model stops: unsupported construct).
"""

import json
import math
import os
import re
import sys

# Cutter radius compensation (G41/G42) is worked out by the tests' own model,
# tests/comp_reference.py (LinuxCNC's rules; no code shared with the firmware).
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
import comp_reference  # noqa: E402

INCH = 25.4
# Region of the machine the scaled job must fit into, machine mm (depth below
# the top switch for Z).
REGION_X = (3.0, 42.0)
REGION_Y = (3.0, 25.0)
REGION_DEPTH = (4.0, 38.0)
# After homing an axis stands this far from its switch ($27), mm; the tool
# changer leaves Z at the travel height, which is the same 1 mm.
PULL_OFF = 1.0
# Chords of the reference arcs deviate at most this much from the circle, mm.
REF_CHORD = 0.0002
# LinuxCNC's canned-cycle defaults: clearance of G83 before re-feeding and the
# G73 chip-break retract (0.010 in in inch mode, 0.254 mm in mm... LinuxCNC
# uses G83_RAPID_DELTA = 0.010 inch for both units).
PECK_CLEARANCE_MM = 0.254
# Retract mode at start: LinuxCNC starts in G98 (none of the corpus states it).
DEFAULT_RETRACT = 98


class Unsupported(Exception):
    pass


# ------------------------------------------------------------------ lexing

WORD_RE = re.compile(r"[A-Za-z]")


def strip_comments(line):
    """The line without (...) and ; comments; None if a comment is unclosed."""
    out = []
    depth = 0
    for c in line:
        if depth:
            if c == ")":
                depth = 0
            continue
        if c == "(":
            depth = 1
            continue
        if c == ";":
            break
        out.append(c)
    return "".join(out)


def tokenize(line):
    """Words of a line as (letter, value_text, start, end) over the raw line,
    comments skipped. value_text is a number (spaces removed), '[expr]' or
    '#..' parameter text. Raises Unsupported on O-word subroutine syntax."""
    words = []
    i = 0
    n = len(line)
    while i < n:
        c = line[i]
        if c == "(":
            j = line.find(")", i)
            i = n if j < 0 else j + 1
            continue
        if c == ";":
            break
        if c.isalpha() or c in "@^":
            letter = c.upper()
            j = i + 1
            while j < n and line[j] in " \t":
                j += 1
            vstart = j
            if j < n and line[j] == "[":
                depth = 0
                while j < n:
                    if line[j] == "[":
                        depth += 1
                    elif line[j] == "]":
                        depth -= 1
                        if depth == 0:
                            j += 1
                            break
                    j += 1
                words.append((letter, line[vstart:j], i, vstart, j))
                i = j
                continue
            if j < n and line[j] == "#":
                k = j + 1
                if k < n and line[k] == "<":
                    k = line.find(">", k) + 1
                else:
                    while k < n and line[k].isdigit():
                        k += 1
                words.append((letter, line[j:k], i, vstart, k))
                i = k
                continue
            # A number: sign, digits, point, with spaces allowed inside.
            k = j
            last = j
            text = []
            while k < n and (line[k] in "+-.0123456789 \t"):
                if line[k] in "+-" and text:
                    break
                if line[k] not in " \t":
                    text.append(line[k])
                    last = k + 1
                k += 1
            words.append((letter, "".join(text), i, vstart, last))
            i = last
            continue
        i += 1
    return words


class Params:
    """LinuxCNC numbered and named parameters, enough for `#2=-1.5` and
    `Z#2` (17_pycam); expressions with + - * / and brackets."""

    def __init__(self):
        self.vals = {}

    def value(self, text):
        if text.startswith("["):
            return self.expr(text)
        if text.startswith("#"):
            key = text[1:].lower()
            if key not in self.vals:
                raise Unsupported("parameter %s not set" % text)
            return self.vals[key]
        if text in ("", "+", "-", "."):
            raise ValueError("bad number")
        return float(text)

    def expr(self, text):
        t = text.lower()
        if re.search(r"[a-z]{2,}", re.sub(r"#<[^>]*>", "", t)):
            raise Unsupported("expression with functions: %s" % text)

        def par(m):
            key = m.group(0)[1:]
            if key not in self.vals:
                raise Unsupported("parameter #%s not set" % key)
            return "(%r)" % self.vals[key]

        t = re.sub(r"#<[^>]*>|#\d+", par, t)
        t = t.replace("[", "(").replace("]", ")")
        if not re.fullmatch(r"[0-9.+\-*/() eE]*", t):
            raise Unsupported("expression %s" % text)
        return float(eval(t, {"__builtins__": {}}, {}))

    def assign(self, stripped):
        """`#n = value` lines; True if the line was an assignment."""
        m = re.fullmatch(r"\s*#(<[^>]*>|\d+)\s*=\s*(.+?)\s*", stripped)
        if not m:
            return False
        key = m.group(1).lower()
        val = m.group(2).replace(" ", "")
        self.vals[key] = self.value(val if val.startswith(("[", "#")) else val)
        return True


# ------------------------------------------------------------ interpreter

CANNED = {81, 82, 83, 73, 85, 89}


class Interp:
    """The reference model. Positions are machine mm (work = machine + G92 +
    nothing else: the firmware's G54..G59 offsets are zero on a fresh
    EEPROM and no corpus file sets them). ``z_up``: home is at the top
    (+Z up); otherwise the firmware's old frame, where machine Z grows
    downward (home pull-off at +1)."""

    def __init__(self, start=(0.0, 0.0, 0.0), z_up=True, bbox_only=False, g80_keeps_motion=True):
        self.pos = list(start)
        # G80 ends only the canned cycle and the motion mode from before it
        # stays (Fanuc, Haas, Mach3; the firmware's default `$154=1`);
        # False: G80 leaves no motion mode (LinuxCNC, `$154=0`).
        self.g80_keeps_motion = g80_keeps_motion
        self.before_cycle = 0
        self.z_up = z_up
        self.inch = False
        self.absolute = True
        self.arc_absolute = False
        self.plane = 17
        self.motion = 0
        self.g92 = [0.0, 0.0, 0.0]
        self.retract = DEFAULT_RETRACT
        self.canned_r = None
        self.canned_q = None
        self.canned_z = None
        self.params = Params()
        self.out = []  # ('L', n) ('P', x, y, z) ('J',)
        self.bbox_only = bbox_only
        # After a tool change Z is where the changer left it (the travel
        # height) until a Z word: points until then are marked.
        self.z_stale = False
        # Cutter compensation: tool radii (tool number -> mm), the spindle
        # tool, the programmed moves since G41/G42 (run through
        # comp_reference at G40), where the tool was at G41/G42.
        self.radii = {}
        self.tool = 0
        self.next_t = 0
        self.comp = None
        self.comp_entry = False
        self.comp_blocks = []
        self.comp_start = None

    # -- output
    def emit(self, p):
        self.pos = list(p)
        self.out.append(("P", p[0], p[1], p[2], self.z_stale))

    def line_to(self, p):
        self.emit(p)

    def unit(self):
        return INCH if self.inch else 1.0

    def work_to_machine(self, axis, v):
        return v * self.unit() + self.g92[axis]

    # -- one block
    def block(self, raw, lineno):
        self.out.append(("L", lineno))
        s = strip_comments(raw).strip()
        if not s or s.startswith("%"):
            return
        if s.startswith("/"):
            s = s[1:]
        if self.params.assign(s):
            return
        words = tokenize(s)
        if not words:
            return
        # O words: a bare program number is a label; anything else is a
        # subroutine/control construct the model does not run.
        if words[0][0] == "O":
            rest = s[words[0][4]:].strip() if len(words[0]) > 4 else ""
            if rest:
                raise Unsupported("O-word %s" % s)
            return
        g = []
        m = []
        val = {}
        for w in words:
            letter, text = w[0], w[1]
            if letter == "N":
                continue
            if "#" in text or text.startswith("["):
                # A parameter used in a word.
                if letter in "GM":
                    raise Unsupported("computed %s word" % letter)
            v = self.params.value(text)
            if letter == "G":
                g.append(round(v, 1))
            elif letter == "M":
                m.append(int(v))
            else:
                if letter in val:
                    raise Unsupported("word %s twice" % letter)
                val[letter] = v
        self.execute(g, m, val, s)

    def execute(self, g, m, val, text):
        g53 = False
        home = False
        for code in g:
            if code == 20:
                self.inch = True
            elif code == 21:
                self.inch = False
            elif code == 90:
                self.absolute = True
            elif code == 91:
                self.absolute = False
            elif code == 90.1:
                self.arc_absolute = True
            elif code == 91.1:
                self.arc_absolute = False
            elif code in (17, 18, 19):
                self.plane = int(code)
            elif code in (98, 99):
                self.retract = int(code)
            elif code in (0, 1, 2, 3):
                self.motion = int(code)
            elif code in CANNED:
                if self.motion not in CANNED:
                    self.before_cycle = self.motion
                self.motion = int(code)
            elif code == 80:
                if not self.g80_keeps_motion:
                    self.motion = None
                elif self.motion in CANNED:
                    self.motion = self.before_cycle
            elif code == 53:
                g53 = True
            elif code == 28:
                home = True
            elif code == 92:
                pass
            elif code == 92.1:
                self.g92 = [0.0, 0.0, 0.0]
            elif code == 40:
                self.comp_off()
            elif code in (41, 42, 41.1, 42.1) and not self.bbox_only:
                d = val.get("D")
                if code in (41.1, 42.1):
                    r = d * self.unit() / 2
                else:
                    r = self.radii.get(str(int(d) if d is not None else self.tool), 0.0)
                if r > 0:
                    self.comp = ("L" if code in (41, 41.1) else "R", r)
                    self.comp_entry = True
                    self.comp_blocks = []
                    self.comp_start = tuple(self.pos)
            elif code in (41, 42, 41.1, 42.1, 4, 49, 43, 54, 55, 56, 57, 58, 59, 61, 61.1, 64, 94):
                pass
            else:
                raise Unsupported("G%s" % code)
        # Tool change: M6 (with or without T) or a T word (this firmware's
        # immediate T, and NGC pre-staging): the changer may run here.
        if "T" in val:
            self.next_t = int(val["T"])
        if 6 in m:
            self.tool = self.next_t
        if 2 in m or 30 in m:
            self.comp_off()
        if 6 in m or "T" in val:
            self.out.append(("J",))
            self.z_stale = True
        if "Z" in val or (self.motion in CANNED and any(a in val for a in "XY")):
            # A Z word, or a canned cycle (its moves state Z): Z known again.
            self.z_stale = False
        polar = "@" in val or "^" in val
        if polar and ("X" in val or "Y" in val or g53 or self.plane != 17):
            raise Unsupported("polar words with X/Y, G53 or outside G17")
        axes = [a for a in "XYZ@^" if a in val]
        if home:
            self.homing(axes or ["X", "Y", "Z"])
            return
        if 92 in g:
            for i, a in enumerate("XYZ"):
                if a in val:
                    self.g92[i] = self.pos[i] - val[a] * self.unit()
            return
        if 10 in g:
            return
        # G4 dwells (no path) and the line goes on to its motion (RS274/NGC
        # order: dwell, then motion).
        # A full circle names only its centre (G2 I-45).
        arc_words = self.motion in (2, 3) and any(k in val for k in "IJKR")
        if not axes and not arc_words:
            return
        if self.motion is None:
            raise Unsupported("axis words with no motion mode")
        target = list(self.pos)
        for i, a in enumerate("XYZ"):
            if a not in val:
                continue
            if g53:
                target[i] = val[a] * self.unit()
            elif self.absolute:
                target[i] = self.work_to_machine(i, val[a])
            else:
                target[i] = self.pos[i] + val[a] * self.unit()
        if self.comp is not None and self.motion in (0, 1, 2, 3):
            if g53 or "R" in val:
                raise Unsupported("G53 or an R arc under compensation")
            centre = None
            if self.motion in (2, 3):
                u = self.unit()
                if self.arc_absolute:
                    centre = (self.work_to_machine(0, val.get("I", 0.0)), self.work_to_machine(1, val.get("J", 0.0)))
                else:
                    centre = (self.pos[0] + val.get("I", 0.0) * u, self.pos[1] + val.get("J", 0.0) * u)
            self.comp_blocks.append(("move", self.motion, tuple(self.pos), tuple(target), centre, self.comp, self.comp_entry))
            if centre is not None or (target[0], target[1]) != (self.pos[0], self.pos[1]):
                self.comp_entry = False
            self.pos = list(target)
            return
        if g53 and self.bbox_only:
            # Machine coordinates are not the job's frame: no bounding box.
            for i, a in enumerate("XYZ"):
                if a in val:
                    target[i] = math.nan
            self.pos = target
        elif self.motion in CANNED:
            self.canned(val)
        else:
            if polar:
                target[0], target[1] = self.polar_point(val, self.absolute, self.pos)
            if self.motion in (0, 1) or g53:
                self.line_to(target)
            else:
                self.arc(target, val, self.motion == 2)

    def polar_point(self, val, absolute, pos):
        """LinuxCNC's polar words (find_ends): `@` radius, `^` angle in
        degrees about the work origin; under G90 a missing one is the
        current point's, under G91 both add to the current point's. Returns
        machine X, Y (mm)."""
        u = self.unit()
        wx, wy = pos[0] - self.g92[0], pos[1] - self.g92[1]
        r0, a0 = math.hypot(wx, wy), math.atan2(wy, wx)
        at_origin = wx == 0 and wy == 0
        if absolute:
            if "^" not in val and at_origin:
                raise Unsupported("polar radius at the origin without an angle")
            r = val["@"] * u if "@" in val else r0
            a = math.radians(val["^"]) if "^" in val else a0
        else:
            if at_origin:
                raise Unsupported("G91 polar move from the origin")
            r = r0 + val.get("@", 0.0) * u
            a = a0 + math.radians(val.get("^", 0.0))
        return r * math.cos(a) + self.g92[0], r * math.sin(a) + self.g92[1]

    def comp_off(self):
        """G40 (or the program's end): the tool path of the moves since
        G41/G42, emitted here; the tool ends where the last one left it."""
        if self.comp is None:
            return
        pts = comp_reference.tool_path(self.comp_blocks + [("off",)], self.comp_start)
        for p in pts[1:]:
            # A move without motion (Z to where it is) adds no point.
            if list(p) != self.pos:
                self.emit(list(p))
        self.comp = None
        self.comp_blocks = []

    def homing(self, axes):
        pull = [PULL_OFF, PULL_OFF, -PULL_OFF if self.z_up else PULL_OFF]
        for a in ("Z", "Y", "X"):
            if a not in axes:
                continue
            i = "XYZ".index(a)
            if i == 2:
                self.z_stale = False
            for v in (0.0, pull[i], 0.0, pull[i]):
                p = list(self.pos)
                p[i] = v
                self.emit(p)
            if self.bbox_only:
                self.pos[i] = math.nan

    def arc(self, target, val, cw):
        a0, a1, an = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}[self.plane]
        off_letters = {0: "I", 1: "J", 2: "K"}
        s = self.pos
        u = self.unit()
        if "R" in val:
            r = val["R"] * u
            dx, dy = target[a0] - s[a0], target[a1] - s[a1]
            d = math.hypot(dx, dy)
            if d == 0:
                raise Unsupported("R arc with end = start")
            h2 = r * r - d * d / 4
            if h2 < 0:
                if h2 < -1e-6 * r * r:
                    raise Unsupported("R arc radius too small")
                h2 = 0.0
            h = math.sqrt(h2)
            # The centre is to the right of start->end for G2 with R > 0.
            sign = -1.0 if cw else 1.0
            if r < 0:
                sign = -sign
            mx, my = (s[a0] + target[a0]) / 2, (s[a1] + target[a1]) / 2
            cx = mx - sign * h * dy / d
            cy = my + sign * h * dx / d
        else:
            def centre(axis):
                letter = off_letters[axis]
                if self.arc_absolute:
                    if letter not in val:
                        raise Unsupported("absolute centre without %s" % letter)
                    return self.work_to_machine(axis, val[letter])
                return s[axis] + val.get(letter, 0.0) * u
            cx, cy = centre(a0), centre(a1)
        r0 = math.hypot(s[a0] - cx, s[a1] - cy)
        r1 = math.hypot(target[a0] - cx, target[a1] - cy)
        t0 = math.atan2(s[a1] - cy, s[a0] - cx)
        t1 = math.atan2(target[a1] - cy, target[a0] - cx)
        sweep = t1 - t0
        full = abs(target[a0] - s[a0]) < 1e-9 and abs(target[a1] - s[a1]) < 1e-9
        if cw:
            while sweep >= 0:
                sweep -= 2 * math.pi
            if full:
                sweep = -2 * math.pi
        else:
            while sweep <= 0:
                sweep += 2 * math.pi
            if full:
                sweep = 2 * math.pi
        turns = int(val.get("P", 1))
        if turns > 1:
            sweep += (turns - 1) * 2 * math.pi * (-1 if cw else 1)
        rmax = max(r0, r1, 1e-9)
        step = 2 * math.acos(max(-1.0, 1 - REF_CHORD / rmax)) if rmax > REF_CHORD else math.pi
        n = max(1, int(math.ceil(abs(sweep) / step)))
        for k in range(1, n + 1):
            f = k / n
            if k == n:
                self.emit(target)
                break
            t = t0 + sweep * f
            r = r0 + (r1 - r0) * f
            p = list(s)
            p[a0] = cx + r * math.cos(t)
            p[a1] = cy + r * math.sin(t)
            p[an] = s[an] + (target[an] - s[an]) * f
            self.out.append(("P", p[0], p[1], p[2], self.z_stale))
        self.pos = list(target)

    def canned(self, val):
        if self.plane != 17:
            raise Unsupported("canned cycle outside G17")
        u = self.unit()
        zi = 2  # Z axis index
        if "R" in val:
            self.canned_r = val["R"]
        if "Q" in val:
            self.canned_q = abs(val["Q"]) * u
        if "Z" in val:
            self.canned_z = val["Z"]
        if self.canned_r is None or self.canned_z is None:
            raise Unsupported("canned cycle without R or Z")
        reps = int(val.get("L", 1))
        initial_z = self.pos[zi]
        if self.absolute:
            r_m = self.work_to_machine(zi, self.canned_r)
            bottom = self.work_to_machine(zi, self.canned_z)
        else:
            r_m = initial_z + self.canned_r * u
            bottom = r_m + self.canned_z * u
        up = 1.0 if self.z_up else -1.0  # the direction of "up" in machine Z

        def above(a, b):  # a is higher than b
            return (a - b) * up > 0

        clear = initial_z if self.retract == 98 and above(initial_z, r_m) else r_m
        # Preliminary: below R, go up to R first.
        if above(r_m, self.pos[zi]):
            p = list(self.pos)
            p[zi] = r_m
            self.emit(p)
        polar = "@" in val or "^" in val
        for _ in range(reps):
            p = list(self.pos)
            if polar:
                # LinuxCNC's CYCLE_MACRO: under G91 each repeat adds the
                # radius and the angle again (holes on a circle).
                p[0], p[1] = self.polar_point(val, self.absolute, self.pos)
            for i, a in enumerate("XY"):
                if a in val:
                    p[i] = self.work_to_machine(i, val[a]) if self.absolute else self.pos[i] + val[a] * u
            self.emit(p)
            p = list(self.pos)
            p[zi] = r_m
            self.emit(p)
            if self.motion in (83, 73) and self.canned_q:
                depth = r_m
                delta = PECK_CLEARANCE_MM
                while above(depth, bottom):
                    nxt = depth - up * self.canned_q
                    if not above(nxt, bottom):
                        nxt = bottom
                    p = list(self.pos)
                    p[zi] = nxt
                    self.emit(p)
                    depth = nxt
                    if not above(depth, bottom):
                        break
                    p = list(self.pos)
                    if self.motion == 83:
                        p[zi] = r_m
                        self.emit(p)
                        p = list(self.pos)
                        p[zi] = depth + up * delta
                        self.emit(p)
                    else:
                        p[zi] = depth + up * delta
                        self.emit(p)
            else:
                p = list(self.pos)
                p[zi] = bottom
                self.emit(p)
            p = list(self.pos)
            p[zi] = clear
            self.emit(p)


def run(text, start, z_up, bbox_only=False, g80_keeps_motion=True, radii=None):
    it = Interp(start, z_up, bbox_only, g80_keeps_motion)
    it.radii = radii or {}
    unsupported = None
    for n, raw in enumerate(text.splitlines(), 1):
        try:
            it.block(raw, n)
        except (Unsupported, ValueError) as e:
            if isinstance(e, ValueError):
                e = "unreadable: %s" % e
            if unsupported is None:
                unsupported = (n, str(e))
            if not bbox_only:
                break
            # The bounding box goes on past what the model cannot run.
    return it, unsupported


# ---------------------------------------------------------------- scaling

def bbox(text):
    """Bounding box (mm) of the commanded path, starting from the first
    point the job states (the position before it is unknown)."""
    it, uns = run(text, (math.nan, math.nan, math.nan), True, bbox_only=True)
    lo = [math.inf] * 3
    hi = [-math.inf] * 3
    for e in it.out:
        if e[0] != "P":
            continue
        for i in range(3):
            v = e[1 + i]
            if not math.isnan(v):
                lo[i] = min(lo[i], v)
                hi[i] = max(hi[i], v)
    for i in range(3):
        if lo[i] == math.inf:
            lo[i] = hi[i] = 0.0
    return lo, hi, uns


def fmt(v, inch):
    s = ("%.5f" if inch else "%.4f") % v
    s = s.rstrip("0").rstrip(".")
    if s in ("-0", ""):
        s = "0"
    return s


def scale_text(text, z_up):
    lo, hi, uns = bbox(text)
    size = [hi[i] - lo[i] for i in range(3)]
    room = [REGION_X[1] - REGION_X[0], REGION_Y[1] - REGION_Y[0], REGION_DEPTH[1] - REGION_DEPTH[0]]
    s = 1.0
    for i in range(3):
        if size[i] > 0:
            s = min(s, room[i] / size[i])
    # A short factor keeps the rewritten numbers short.
    s = math.floor(s * 1e4) / 1e4
    t = [0.0, 0.0, 0.0]
    t[0] = (REGION_X[0] + REGION_X[1]) / 2 - s * (lo[0] + hi[0]) / 2
    t[1] = (REGION_Y[0] + REGION_Y[1]) / 2 - s * (lo[1] + hi[1]) / 2
    if z_up:
        t[2] = -REGION_DEPTH[0] - s * hi[2]
    else:
        t[2] = REGION_DEPTH[0] - s * lo[2]
    t = [round(v, 3) for v in t]

    out = ["G28 (corpus_scale.py: home first, s=%g t=%g,%g,%g mm)" % (s, t[0], t[1], t[2])]
    st = Interp((0, 0, 0), z_up)  # modal state only
    canned_active = False
    for raw in text.splitlines():
        body = strip_comments(raw)
        try:
            words = tokenize(raw) if body.strip() and not st.params.assign(body.strip()) else []
        except Unsupported:
            words = []
        except ValueError:
            words = []
        gs = []
        for w in words:
            if w[0] == "G":
                try:
                    gs.append(round(float(w[1]), 1))
                except ValueError:
                    pass
        for code in gs:
            if code == 20:
                st.inch = True
            elif code == 21:
                st.inch = False
            elif code == 90:
                st.absolute = True
            elif code == 91:
                st.absolute = False
            elif code == 90.1:
                st.arc_absolute = True
            elif code == 91.1:
                st.arc_absolute = False
            elif code in CANNED:
                canned_active = True
            elif code in (0, 1, 2, 3, 80):
                canned_active = False
        if 53 in gs or 10 in gs or not words:
            out.append(raw)
            continue
        u = INCH if st.inch else 1.0
        tt = [v / u for v in t]
        rep = []
        for w in words:
            letter, val = w[0], w[1]
            absolute_pos = None  # axis index when the word is a position
            if letter in "XYZ":
                axis = "XYZ".index(letter)
                absolute_pos = axis if (st.absolute or 92 in gs) else None
                kind = "len" if absolute_pos is None else "pos"
            elif letter in "IJK":
                axis = "IJK".index(letter)
                kind = "pos" if st.arc_absolute else "len"
                absolute_pos = axis
            elif letter == "R":
                if canned_active:
                    kind = "pos" if st.absolute else "len"
                    axis = 2
                    absolute_pos = 2
                else:
                    kind = "len"
            elif letter == "Q" and canned_active:
                kind = "len"
            else:
                continue
            if val.startswith("[") or val.startswith("#"):
                inner = val[1:-1] if val.startswith("[") else val
                if kind == "pos":
                    new = "[[%s]*%s+%s]" % (inner, fmt(s, False), fmt(tt[absolute_pos], st.inch))
                else:
                    new = "[[%s]*%s]" % (inner, fmt(s, False))
            else:
                try:
                    v = float(val)
                except ValueError:
                    continue
                nv = s * v + (tt[absolute_pos] if kind == "pos" else 0.0)
                new = fmt(nv, st.inch)
            rep.append((w[3], w[4], new))
        line = raw
        for a, b, new in sorted(rep, reverse=True):
            line = line[:a] + new + line[b:]
        out.append(line)
    params = {"scale": s, "translate_mm": t, "bbox_mm": [lo, hi], "units_kept": True}
    if uns:
        params["model_stops"] = {"line": uns[0], "why": uns[1]}
    return "\n".join(out) + "\n", params


def selftest():
    """Checks of the reference model on small jobs with known paths
    (run by tests/corpus.rs)."""
    def path(text, z_up=True, start=(0.0, 0.0, 0.0)):
        it, uns = run(text, start, z_up)
        assert uns is None, uns
        return [list(e[1:4]) for e in it.out if e[0] == "P"]

    def close(a, b, tol=1e-6):
        return all(abs(x - y) <= tol for x, y in zip(a, b))

    # Full circle by I/J: ends at its start, every point on the circle, the
    # chords within REF_CHORD, in every plane and both directions.
    for plane, (a0, a1) in ((17, (0, 1)), (18, (2, 0)), (19, (1, 2))):
        for g in (2, 3):
            off = {17: "I-5 J0", 18: "K-5 I0", 19: "J-5 K0"}[plane]
            start = [10.0, 10.0, -10.0]
            pts = path("G21 G90 G%d\nG0 X10 Y10 Z-10\nG%d %s F100\n" % (plane, g, off))
            arc = pts[1:]
            assert close(arc[-1], start), (plane, g, arc[-1])
            c = list(start)
            c[a0] -= 5
            for p in arc:
                assert abs(math.hypot(p[a0] - c[a0], p[a1] - c[a1]) - 5) < 1e-9
            swept = 0.0
            prev = math.atan2(start[a1] - c[a1], start[a0] - c[a0])
            for p in arc:
                t = math.atan2(p[a1] - c[a1], p[a0] - c[a0])
                d = (t - prev + math.pi) % (2 * math.pi) - math.pi
                swept += d
                prev = t
            assert abs(abs(swept) - 2 * math.pi) < 1e-6, swept
            assert (swept < 0) == (g == 2), (plane, g, swept)
    # R arcs: R > 0 the short way, R < 0 the long way round; G2 clockwise.
    short = path("G0 X0 Y0\nG2 X10 Y0 R5 F100\n")
    assert max(p[1] for p in short) > 4.99 and min(p[1] for p in short) > -1e-9
    long_ = path("G0 X0 Y0\nG2 X10 Y10 R-10 F100\n")
    assert close(long_[-1], (10, 10, 0))
    assert max(p[1] for p in long_) > 19.99 and min(p[0] for p in long_) < -9.99, "R<0 goes the long way"
    short = path("G0 X0 Y0\nG2 X10 Y10 R10 F100\n")
    assert max(p[0] for p in short) < 10 + 1e-9 and min(p[0] for p in short) > -1e-9, "R>0 the short way"
    # G90.1 absolute centres vs G91.1 incremental.
    a = path("G0 X5 Y0\nG90.1 G3 X-5 Y0 I0 J0 F100\n")
    b = path("G0 X5 Y0\nG91.1 G3 X-5 Y0 I-5 J0 F100\n")
    assert a == b and max(p[1] for p in a) > 4.99
    # Helix: Z linear in the angle.
    h = path("G0 X5 Y0 Z0\nG3 X5 Y0 Z-4 I-5 J0 F100\n")
    assert close(h[-1], (5, 0, -4))
    mid = h[len(h) // 2]
    assert abs(mid[2] + 2) < 0.05
    # G20, G91, G92.
    assert close(path("G20 G0 X1 Y2\n")[-1], (25.4, 50.8, 0))
    assert close(path("G91 G0 X1\nX1\nY-2\n")[-1], (2, -2, 0))
    assert close(path("G0 X5\nG92 X0\nG0 X1\n")[-1], (6, 0, 0))
    # G28: Z, Y, X, each to the switch, 1 mm off, back, 1 mm off; +Z up.
    g28 = path("G28\n", start=(10.0, 20.0, -30.0))
    assert [p[2] for p in g28[:4]] == [0, -1, 0, -1], g28[:4]
    assert close(g28[-1], (1, 1, -1))
    assert path("G28\n", z_up=False, start=(10.0, 20.0, 30.0))[3][2] == 1
    # Canned cycles (LinuxCNC): G81 from Z5, R1, Z-2, G98 returns to 5,
    # G99 to R; G83 Q1 pecks back to R; modal holes on bare X/Y.
    d = path("G0 X0 Y0 Z5\nG98 G81 X3 Y4 R1 Z-2 F100\nX6\nG80\n")
    assert [tuple(p) for p in d] == [(0, 0, 5), (3, 4, 5), (3, 4, 1), (3, 4, -2), (3, 4, 5),
                                     (6, 4, 5), (6, 4, 1), (6, 4, -2), (6, 4, 5)], d
    d = path("G0 X0 Y0 Z5\nG99 G81 X3 Y4 R1 Z-2 F100\n")
    assert d[-1] == [3, 4, 1]
    d = path("G0 X0 Y0 Z5\nG99 G83 X0 Y0 R1 Z-2 Q1 F100\n")
    zs = [round(p[2], 3) for p in d]
    assert zs == [5, 5, 1, 0, 1, 0.254, -1, 1, -0.746, -2, 1], zs
    # G91 canned: R relative to the start Z, Z relative to R, L repeats.
    d = path("G0 X0 Y0 Z5\nG91 G99 G81 X2 R-4 Z-3 L2 F100\n")
    assert [tuple(round(v, 6) for v in p) for p in d[-3:]] == [(4, 0, 1), (4, 0, -2), (4, 0, 1)], d
    # G80 keeps the motion mode from before the cycle (Fanuc, Mach3);
    # with --g80-cancels bare axis words after it stop the model.
    d = path("G0 X0 Y0 Z5\nG98 G73 X10 Y10 Z-11 R-5 Q4 F250\nG80\nZ-4\nX12 Y12 Z-4\n")
    assert close(d[-2], (10, 10, -4)) and close(d[-1], (12, 12, -4)), d[-3:]
    it, uns = run("G0 X0\nG81 X1 R1 Z0 F1\nG80\nX2\n", (0.0, 0.0, 5.0), True, g80_keeps_motion=False)
    assert uns and uns[0] == 4, uns
    # Polar words about the work origin: G90 absolute, G91 added.
    d = path("G0 X10 Y0\nG1 @5 ^90 F100\nG91 ^90\n@1\n")
    assert close(d[1], (0, 5, 0)) and close(d[2], (-5, 0, 0)) and close(d[3], (-6, 0, 0)), d
    # G91 G81 ^60 L6: six holes on the circle.
    d = path("G0 X10 Y0 Z5\nG91 G98 G81 R-4 Z-2 ^60 L6 F100\n")
    bottoms = [p for p in d if abs(p[2] - -1) < 1e-9]
    assert len(bottoms) == 6 and close(bottoms[-1], (10, 0, -1), 1e-9) and close(bottoms[0], (5, 8.660254037844386, -1)), bottoms
    # G4 on a motion line: the dwell, then the move (RS274/NGC order).
    assert close(path("G0 X1\nG04 P.5 G0 X10 Y10 S1000 M3\n")[-1], (10, 10, 0))
    # Scaling: numbers only, uniform factor, G91 and R only scaled.
    out, params = scale_text("G21 G90\nG0 X0 Y0 Z0\nG1 X100 Y10 Z-10 F500 (c X1)\nG2 X100 Y30 R10\nG91 G1 X-10\n", True)
    lines = out.splitlines()
    s = params["scale"]
    assert lines[0].startswith("G28") and abs(s - 0.39) < 1e-9, params
    assert "F500 (c X1)" in lines[3] and lines[4].endswith("R%s" % fmt(10 * s, False)), lines
    assert lines[5] == "G91 G1 X%s" % fmt(-10 * s, False), lines
    print("corpus_scale.py self-test: ok")


def main(argv):
    if len(argv) >= 3 and argv[0] == "scale":
        z_up = "--z-down" not in argv
        text = open(argv[1], encoding="latin-1").read()
        scaled, params = scale_text(text, z_up)
        with open(argv[2], "w", encoding="latin-1") as f:
            f.write(scaled)
        print(json.dumps(params))
        return 0
    if len(argv) >= 3 and argv[0] == "path":
        z_up = "--z-down" not in argv
        start = (0.0, 0.0, 0.0)
        if "--start" in argv:
            start = tuple(float(v) for v in argv[argv.index("--start") + 1].split(","))
        radii = json.loads(argv[argv.index("--radii") + 1]) if "--radii" in argv else {}
        text = open(argv[1], encoding="latin-1").read()
        it, uns = run(text, start, z_up, g80_keeps_motion="--g80-cancels" not in argv, radii=radii)
        if uns is None:
            it.comp_off()
        with open(argv[2], "w") as f:
            for e in it.out:
                if e[0] == "P":
                    f.write("P %.6f %.6f %.6f %d\n" % (e[1], e[2], e[3], 1 if e[4] else 0))
                elif e[0] == "L":
                    f.write("L %d\n" % e[1])
                else:
                    f.write("J\n")
            if uns:
                f.write("U %d %s\n" % (uns[0], uns[1]))
        return 0
    if argv and argv[0] == "selftest":
        selftest()
        return 0
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
