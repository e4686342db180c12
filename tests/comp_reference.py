#!/usr/bin/env python3
"""Reference tool-centre path under cutter radius compensation (G41/G42),
for tests/dialect.rs and tests/corpus.rs: written from LinuxCNC's rules
(interp_convert.cc, convert_straight_comp1/2 and convert_arc_comp1/2), and
sharing no code with the firmware. The whole program is read first and the
tool path worked out afterwards (the firmware streams with one move of
look-ahead); arcs are angles and radii here, vectors there; inside corners
are found by bisection along the next move, not in closed form.

    comp_reference.py '{"1": 0.5}' X Y Z < job.ngc

The JSON maps tool numbers to radii (mm); X Y Z is where the tool starts
(work mm, +Z up). Understands G0-G3 (I/J centres), G17, G20/G21, G90,
G40-G42.1 with D, F, and ignores the other codes. Prints a JSON list of
[x, y, z] points, arcs as chords within 0.0001 mm.
"""
import json
import math
import re
import sys

TAU = 2 * math.pi


def words(line):
    line = re.sub(r"\([^)]*\)", " ", line).split(";")[0].upper()
    return re.findall(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))", line.replace(" ", ""))


def read_program(text, radii, start):
    """The programmed moves, each with the compensation in force."""
    pos = list(start)
    scale = 1.0
    motion = 0
    side, radius, entry = None, 0.0, False
    blocks = []
    for raw in text.splitlines():
        w = words(raw)
        g = [float(v) for k, v in w if k == "G"]
        val = {k: float(v) for k, v in w if k not in "GMNT"}
        if 20 in g:
            scale = 25.4
        if 21 in g:
            scale = 1.0
        for code in g:
            if code in (0, 1, 2, 3):
                motion = int(code)
        if 40 in g:
            blocks.append(("off",))
            side = None
        for code, s in ((41, "L"), (42, "R"), (41.1, "L"), (42.1, "R")):
            if code in g:
                d = val.get("D")
                r = d * scale / 2 if code in (41.1, 42.1) else radii.get(str(int(d)), 0.0)
                side, radius, entry = s, r, True
        end = list(pos)
        for i, k in enumerate("XYZ"):
            if k in val:
                end[i] = val[k] * scale
        is_arc = motion in (2, 3) and ("I" in val or "J" in val)
        if end == pos and not is_arc:
            continue
        centre = None
        if is_arc:
            centre = (pos[0] + val.get("I", 0.0) * scale, pos[1] + val.get("J", 0.0) * scale)
        comp = (side, radius) if side and radius > 0 else None
        blocks.append(("move", motion, tuple(pos), tuple(end), centre, comp, entry and comp is not None))
        if comp and (end[0], end[1]) != (pos[0], pos[1]) or is_arc:
            entry = False
        pos = end
    return blocks


def angle_of(c, p):
    return math.atan2(p[1] - c[1], p[0] - c[0])


def sweep(a0, a1, ccw, full):
    d = (a1 - a0) if ccw else (a0 - a1)
    d %= TAU
    if full and d < 1e-9:
        d = TAU
    return d


class Elem:
    """A piece of tool path: a line, or an arc (centre, radius, ccw)."""

    def __init__(self, start, end, z0, z1, centre=None, ccw=True, full=False):
        self.start, self.end, self.z0, self.z1 = start, end, z0, z1
        self.centre, self.ccw, self.full = centre, ccw, full

    def radius(self):
        return math.dist(self.start, self.centre)

    def point(self, s):
        """The point at fraction s of the way (XY)."""
        if self.centre is None:
            return (self.start[0] + s * (self.end[0] - self.start[0]), self.start[1] + s * (self.end[1] - self.start[1]))
        a0 = angle_of(self.centre, self.start)
        sw = sweep(a0, angle_of(self.centre, self.end), self.ccw, self.full)
        a = a0 + (s * sw if self.ccw else -s * sw)
        r = self.radius()
        return (self.centre[0] + r * math.cos(a), self.centre[1] + r * math.sin(a))

    def signed(self, p):
        """Signed distance of p from the path's line or circle."""
        if self.centre is None:
            dx, dy = self.end[0] - self.start[0], self.end[1] - self.start[1]
            return (dx * (p[1] - self.start[1]) - dy * (p[0] - self.start[0])) / math.hypot(dx, dy)
        return math.dist(p, self.centre) - self.radius()

    def points(self):
        if self.centre is None:
            return [(*self.end, self.z1)]
        r = self.radius()
        sw = sweep(angle_of(self.centre, self.start), angle_of(self.centre, self.end), self.ccw, self.full)
        n = max(1, math.ceil(sw / (2 * math.acos(max(-1.0, 1 - 0.0001 / r)))))
        out = []
        for i in range(1, n + 1):
            x, y = self.point(i / n)
            out.append((x, y, self.z0 + (self.z1 - self.z0) * i / n))
        out[-1] = (*self.end, self.z1)
        return out


def offset_point(p, centre, ccw, side, r, direction=None):
    """p moved r to the side of the path (a line's direction, or an arc)."""
    if centre is None:
        a = math.atan2(direction[1], direction[0]) + (math.pi / 2 if side == "L" else -math.pi / 2)
        return (p[0] + r * math.cos(a), p[1] + r * math.sin(a))
    inside = (side == "L") == ccw
    R = math.dist(p, centre)
    if inside and R <= r:
        raise ValueError("gouge: concave arc smaller than the tool")
    k = (R - r if inside else R + r) / R
    return (centre[0] + (p[0] - centre[0]) * k, centre[1] + (p[1] - centre[1]) * k)


def tool_path(blocks, start):
    tool = (start[0], start[1])
    z = start[2]
    out = [tuple(start)]
    held = None  # (Elem, programmed corner)

    def flush():
        nonlocal held
        if held is not None:
            out.extend(held[0].points())
            held = None

    for b in blocks:
        if b[0] == "off":
            flush()
            continue
        _, motion, p0, p1, centre, comp, entry = b
        ccw = motion == 3
        full = centre is not None and (p0[0], p0[1]) == (p1[0], p1[1])
        if comp is None:
            flush()
            e = Elem(tool, (p1[0], p1[1]), z, p1[2], centre, ccw, full)
            out.extend(e.points())
            tool, z = e.end, p1[2]
            continue
        side, r = comp
        if (p0[0], p0[1]) == (p1[0], p1[1]) and centre is None:
            # No move in the plane: the held move goes first.
            flush()
            out.append((*tool, p1[2]))
            z = p1[2]
            continue
        if entry:
            flush()
            if math.dist(tool, p1[:2]) <= r:
                raise ValueError("entry move not longer than the radius")
            if centre is None:
                end = offset_point(p1[:2], None, ccw, side, r, (p1[0] - tool[0], p1[1] - tool[1]))
                e = Elem(tool, end, z, p1[2])
            else:
                end = offset_point(p1[:2], centre, ccw, side, r)
                # LinuxCNC: the centre moves along the end's radius until it
                # is as far from the start as from the end.
                ab = math.atan2(centre[1] - end[1], centre[0] - end[0])
                b_len = math.dist(tool, end) / 2
                a_ang = math.atan2(tool[1] - end[1], tool[0] - end[0]) - ab
                c_len = b_len / math.cos(a_ang)
                c = (end[0] + c_len * math.cos(ab), end[1] + c_len * math.sin(ab))
                e = Elem(tool, end, z, p1[2], c, ccw, False)
            held = (e, p1[:2])
            tool, z = e.end, p1[2]
            continue
        # A later move: its offset, then the corner with the held one.
        if centre is None:
            d = (p1[0] - p0[0], p1[1] - p0[1])
            q0 = offset_point(p0[:2], None, ccw, side, r, d)
            q1 = offset_point(p1[:2], None, ccw, side, r, d)
            nxt = Elem(q0, q1, z, p1[2])
        else:
            q0 = offset_point(p0[:2], centre, ccw, side, r)
            q1 = offset_point(p1[:2], centre, ccw, side, r)
            nxt = Elem(q0, q1, z, p1[2], centre, ccw, full)
        prev, corner = held if held else (None, p0[:2])
        t_prev = angle_of(corner, prev.end if prev else tool)
        t_next = angle_of(corner, q0)
        turn = (t_next - t_prev + math.pi) % TAU - math.pi  # from one normal to the other
        if abs(turn) < 1e-4:
            pass
        elif (turn > 0) == (side == "L") and abs(abs(turn) - math.pi) > 1e-4:
            if prev is None:
                raise ValueError("inside corner after the held move was sent")
            # Inside: the first point of the next move on the held one's path.
            f = lambda s: prev.signed(nxt.point(s))
            n = 2000
            s0, found = 0.0, None
            for i in range(1, n + 1):
                s1 = i / n
                if f(s0) * f(s1) <= 0:
                    lo, hi = s0, s1
                    for _ in range(60):
                        mid = (lo + hi) / 2
                        if f(lo) * f(mid) <= 0:
                            hi = mid
                        else:
                            lo = mid
                    found = nxt.point((lo + hi) / 2)
                    break
                s0 = s1
            if found is None:
                raise ValueError("gouge: inside corner not reachable")
            prev.end = found
            nxt.start = found
            held = (prev, corner)
        else:
            flush()
            tool = out[-1][:2]
            arc = Elem(tool, q0, z, z, corner, side == "R", False)
            out.extend(arc.points())
        flush()
        held = (nxt, p1[:2])
        tool, z = nxt.end, p1[2]
    flush()
    return out


def main():
    radii = json.loads(sys.argv[1])
    start = [float(v) for v in sys.argv[2:5]]
    blocks = read_program(sys.stdin.read(), radii, start)
    print(json.dumps([list(p) for p in tool_path(blocks, start)]))


if __name__ == "__main__":
    main()
