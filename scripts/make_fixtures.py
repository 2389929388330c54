#!/usr/bin/env python3
"""Writes the compensation fixtures under fixtures/programs/: the paper's three rectangular
validation paths (Ibaraki et al., Fig. 8: X400 x Y2000 mm rectangles stopping every 100 mm,
over a Z range of 1000 mm) as KRL programs in three styles, and a path with a vertical
segment. Placement inside the KR 30 HA workspace: $BASE at X1000 Y-1000 Z400 in the robot
base, so the rectangles span base X0..400, Y0..2000 at base Z500 (Path 1, the paper's
"Z500"), Z0 (Path 2) and Z1000 (Path 3); a 200 mm spindle tool pointing down."""
import os

OUT = "fixtures/programs"
BASE = "{X 1000.0,Y -1000.0,Z 400.0,A 0.0,B 0.0,C 0.0}"
TOOL = "{X 0.0,Y 0.0,Z 200.0,A 0.0,B 0.0,C 0.0}"
ORI = (0.0, 0.0, 180.0)


def rectangle(z):
    """Stops every 100 mm around X0..400 x Y0..2000, counter-clockwise from the origin."""
    pts = []
    for y in range(0, 2000, 100):
        pts.append((0.0, float(y)))
    for x in range(0, 400, 100):
        pts.append((float(x), 2000.0))
    for y in range(2000, 0, -100):
        pts.append((400.0, float(y)))
    for x in range(400, 0, -100):
        pts.append((float(x), 0.0))
    pts.append((0.0, 0.0))
    return [(x, y, z) for x, y in pts]


def pos(x, y, z, decimals=3):
    a, b, c = ORI
    f = f"{{:.{decimals}f}}"
    return "{X %s,Y %s,Z %s,A %s,B %s,C %s}" % tuple(f.format(v) for v in (x, y, z, a, b, c))


def write(name, text, crlf):
    path = os.path.join(OUT, name)
    data = text.replace("\n", "\r\n") if crlf else text
    with open(path, "w", newline="") as f:
        f.write(data)


# Path 1: inline aggregates in the .src (CAM style), CRLF.
pts = rectangle(500.0)
lines = [
    "&ACCESS RVP",
    "&REL 1",
    "DEF paper_path1( )",
    "; Paper validation path 1: X400 x Y2000 mm rectangle at base Z500, a stop every 100 mm.",
    "DECL E6AXIS XHOME",
    "XHOME={A1 0.0,A2 -90.0,A3 90.0,A4 0.0,A5 0.0,A6 0.0,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}",
    "$BASE=" + BASE,
    "$TOOL=" + TOOL,
    "PTP XHOME",
    "PTP {X 0.0,Y 0.0,Z 600.0,A 0.0,B 0.0,C 180.0,S 2,T 34}",
]
for x, y, z in pts:
    lines.append("LIN " + pos(x, y, z))
lines += ["LIN {Z 600.0}", "PTP XHOME", "END", ""]
write("paper_path1.src", "\n".join(lines), True)
write("paper_path1.dat", "&ACCESS RVP\n&REL 1\nDEFDAT paper_path1\nENDDAT\n", True)

# Path 2: named points in the .dat, motions by name, CRLF.
pts = rectangle(0.0)
src = [
    "&ACCESS RVP",
    "&REL 1",
    "DEF paper_path2( )",
    "; Paper validation path 2: X400 x Y2000 mm rectangle at base Z0, points in the data list.",
    "$BASE=" + BASE,
    "$TOOL=" + TOOL,
    "PTP HOME",
    "PTP APPROACH",
]
dat = [
    "&ACCESS RVP",
    "&REL 1",
    "DEFDAT paper_path2",
    "DECL E6AXIS HOME={A1 0.0,A2 -90.0,A3 90.0,A4 0.0,A5 0.0,A6 0.0,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}",
    "DECL E6POS APPROACH={X 0.0,Y 0.0,Z 100.0,A 0.0,B 0.0,C 180.0,S 2,T 34,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}",
]
for i, (x, y, z) in enumerate(pts, 1):
    src.append(f"LIN P{i} C_DIS")
    dat.append(f"DECL E6POS P{i}=" + pos(x, y, z, 2)[:-1] + ",S 2,T 34,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}")
src += ["LIN APPROACH", "PTP HOME", "END", ""]
dat += ["ENDDAT", ""]
write("paper_path2.src", "\n".join(src), True)
write("paper_path2.dat", "\n".join(dat), True)

# Path 3: a FRAME array in the .dat driven by a FOR loop, LF line endings.
pts = rectangle(1000.0)
n = len(pts)
src = [
    "DEF paper_path3( )",
    "  ; Paper validation path 3: X400 x Y2000 mm rectangle at base Z1000, a CAM-style",
    "  ; FRAME array in the data list driven by a FOR loop.",
    "  DECL INT I",
    "  $BASE = " + BASE.replace(",", ", "),
    "  $TOOL = " + TOOL.replace(",", ", "),
    "  PTP {A1 0, A2 -90, A3 90, A4 0, A5 0, A6 0}",
    "  PTP {X 0, Y 0, Z 1050, A 0, B 0, C 180, S 2, T 34}",
    "  FOR I = 1 TO NPTS",
    "    LIN PATH3[I] C_DIS",
    "  ENDFOR",
    "  LIN_REL {Z 50} #BASE",
    "  PTP {A1 0, A2 -90, A3 90, A4 0, A5 0, A6 0}",
    "END",
    "",
]
dat = ["DEFDAT paper_path3", f"  DECL INT NPTS = {n}", f"  DECL FRAME PATH3[{n}]"]
for i, (x, y, z) in enumerate(pts, 1):
    dat.append(f"  PATH3[{i}] = {{X {x:.1f}, Y {y:.1f}, Z {z:.1f}, A 0.0, B 0.0, C 180.0}}")
dat += ["ENDDAT", ""]
write("paper_path3.src", "\n".join(src), False)
write("paper_path3.dat", "\n".join(dat), False)

# A vertical segment: straight down and up again at fixed orientation (A1 rests).
src = [
    "&ACCESS RVP",
    "&REL 1",
    "DEF vertical_segment( )",
    "; A1 (and the wrist) rest while the TCP moves straight down: the backlash case of issue 4.",
    "$BASE=$NULLFRAME",
    "$TOOL=" + TOOL,
    "PTP {A1 20.0,A2 -80.0,A3 100.0,A4 0.0,A5 70.0,A6 0.0}",
    "LIN {X 1300.0,Y 450.0,Z 1200.0,A 0.0,B 0.0,C 180.0}",
]
for k in range(1, 11):
    src.append("LIN {Z %.3f}" % (1200.0 - 60.0 * k))
for k in range(9, -1, -1):
    src.append("LIN {Z %.3f}" % (1200.0 - 60.0 * k))
src += ["END", ""]
write("vertical_segment.src", "\n".join(src), True)
