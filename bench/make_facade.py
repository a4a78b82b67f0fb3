#!/usr/bin/env python3
"""Writes examples/scenes/facade.rib: the paper's Plate 2, a sandstone facade in late-afternoon sun.

The facade is generated rather than typed because its ~1,250 input triangles are a few hundred
stone blocks; rerun this after changing the layout. The variants (Plate 3 without shadows, the
displaced-pixel mask, a street of N facades) are options:
  make_facade.py [out.rib] [--noshadows | --mask] [--copies N] [--edge L]
"""
import argparse
import os

WALL_X = (-5.4, 5.4)
PLINTH_TOP = 1.6      # craggy rusticated base below, grooved ashlar above
ASHLAR_TOP = 4.8      # the cornice starts here
WIN_X = (-1.0, 1.0)   # window opening
WIN_Y = (2.0, 4.0)
RECESS = 0.3          # depth of the window reveal
JOINT = 0.03          # open joint between stones, showing the backing wall
EDGE = 0.017          # world-space subdivision target: sets the displaced triangle count
FLATNESS = 0.001      # simplification tolerance (paper 3.1): flat stretches stay coarser


class Mesh:
    """Quads as one PointsPolygons; each quad is split into an nu x nv grid with its own st."""

    def __init__(self):
        self.P, self.st, self.polys = [], [], []

    def quad(self, p00, p10, p11, p01, nu=1, nv=1, s=(0.0, 1.0), t=(0.0, 1.0)):
        def lerp(a, b, x):
            return [a[k] + (b[k] - a[k]) * x for k in range(3)]

        base = len(self.P)
        for j in range(nv + 1):
            y = j / nv
            for i in range(nu + 1):
                x = i / nu
                self.P.append(lerp(lerp(p00, p10, x), lerp(p01, p11, x), y))
                self.st.append((s[0] + (s[1] - s[0]) * x, t[0] + (t[1] - t[0]) * y))
        for j in range(nv):
            for i in range(nu):
                a = base + j * (nu + 1) + i
                self.polys.append((a, a + 1, a + nu + 2, a + nu + 1))

    def triangles(self):
        return 2 * len(self.polys)

    def rib(self, indent="    "):
        f = lambda v: ("%.4f" % v).rstrip("0").rstrip(".") or "0"
        out = [indent + "PointsPolygons [" + " ".join("4" for _ in self.polys) + "]"]
        out.append(indent + "  [" + " ".join(" ".join(str(i) for i in q) for q in self.polys) + "]")
        out.append(indent + '  "P" [' + "  ".join(" ".join(f(c) for c in p) for p in self.P) + "]")
        out.append(indent + '  "st" [' + "  ".join(f(a) + " " + f(b) for a, b in self.st) + "]")
        return "\n".join(out)


def in_window(x0, x1, y0, y1):
    return x1 > WIN_X[0] and x0 < WIN_X[1] and y1 > WIN_Y[0] and y0 < WIN_Y[1]


def blocks(mesh, y0, y1, rows, width, nu, nv, skip_window):
    """Running-bond courses of stones between y0 and y1, each stone a face at z = 0."""
    h = (y1 - y0) / rows
    for r in range(rows):
        by0, by1 = y0 + r * h + JOINT / 2, y0 + (r + 1) * h - JOINT / 2
        x = WALL_X[0] - (width / 2 if r % 2 else 0)
        while x < WALL_X[1]:
            bx0, bx1 = max(x, WALL_X[0]) + JOINT / 2, min(x + width, WALL_X[1]) - JOINT / 2
            x += width
            if skip_window:
                # Stones beside the opening are cut to it, so the reveal has a clean edge.
                if in_window(bx0, bx1, by0, by1):
                    if bx0 < WIN_X[0] < bx1:
                        bx1 = WIN_X[0]
                    elif bx0 < WIN_X[1] < bx1:
                        bx0 = WIN_X[1]
                    else:
                        continue
            if bx1 - bx0 < 0.05:
                continue
            # s runs 0.5..1.5 across the stone so the shader's grooves repeat evenly from its edges.
            mesh.quad([bx0, by0, 0], [bx1, by0, 0], [bx1, by1, 0], [bx0, by1, 0], nu, nv,
                      s=(0.0, (bx1 - bx0)), t=(0.0, 1.0))


def build_parts():
    plinth, ashlar, cornice, sill, reveal, glass, backing = (Mesh() for _ in range(7))
    blocks(plinth, 0.0, PLINTH_TOP, 2, 1.5, 4, 2, False)
    blocks(ashlar, PLINTH_TOP, ASHLAR_TOP, 8, 0.8, 2, 1, True)

    # Cornice profile along x: soffit, fascia, cove, crown band, top.
    prof = [(ASHLAR_TOP, 0.0), (ASHLAR_TOP, -0.25), (ASHLAR_TOP + 0.2, -0.25),
            (ASHLAR_TOP + 0.45, -0.45), (ASHLAR_TOP + 0.65, -0.45), (ASHLAR_TOP + 0.65, 0.0)]
    x0, x1 = WALL_X[0] - 0.2, WALL_X[1] + 0.2
    for (ya, za), (yb, zb) in zip(prof, prof[1:]):
        cornice.quad([x0, ya, za], [x1, ya, za], [x1, yb, zb], [x0, yb, zb], 14, 1,
                     s=(0.0, x1 - x0))

    # Windowsill: a slab under the opening, standing out of the wall.
    sx0, sx1, sy0, sy1, sz = WIN_X[0] - 0.25, WIN_X[1] + 0.25, WIN_Y[0] - 0.16, WIN_Y[0], -0.22
    sill.quad([sx0, sy1, 0], [sx1, sy1, 0], [sx1, sy1, sz], [sx0, sy1, sz], 8, 1)    # top
    sill.quad([sx0, sy0, sz], [sx1, sy0, sz], [sx1, sy1, sz], [sx0, sy1, sz], 8, 1)  # front
    sill.quad([sx0, sy0, 0], [sx1, sy0, 0], [sx1, sy0, sz], [sx0, sy0, sz], 8, 1)    # underside
    for x in (sx0, sx1):
        sill.quad([x, sy0, 0], [x, sy0, sz], [x, sy1, sz], [x, sy1, 0], 1, 1)

    # Window reveal (the recess) and the pane at its back: four panes of bumpy glass, each with
    # bevelled edges (glassbumps.disp works in the pane's own st).
    (wx0, wx1), (wy0, wy1) = WIN_X, WIN_Y
    reveal.quad([wx0, wy0, 0], [wx0, wy0, RECESS], [wx0, wy1, RECESS], [wx0, wy1, 0], 1, 8)
    reveal.quad([wx1, wy0, 0], [wx1, wy0, RECESS], [wx1, wy1, RECESS], [wx1, wy1, 0], 1, 8)
    reveal.quad([wx0, wy1, 0], [wx1, wy1, 0], [wx1, wy1, RECESS], [wx0, wy1, RECESS], 8, 1)
    reveal.quad([wx0, wy0, 0], [wx1, wy0, 0], [wx1, wy0, RECESS], [wx0, wy0, RECESS], 8, 1)
    for i in range(2):
        for j in range(2):
            ax0, ax1 = wx0 + (wx1 - wx0) * i / 2, wx0 + (wx1 - wx0) * (i + 1) / 2
            ay0, ay1 = wy0 + (wy1 - wy0) * j / 2, wy0 + (wy1 - wy0) * (j + 1) / 2
            glass.quad([ax0, ay0, RECESS], [ax1, ay0, RECESS], [ax1, ay1, RECESS],
                       [ax0, ay1, RECESS], 3, 3)

    # Backing wall behind the open joints (undisplaced), with the opening cut out.
    bz = 0.05
    bx0, bx1 = WALL_X
    backing.quad([bx0, 0, bz], [wx0, 0, bz], [wx0, ASHLAR_TOP, bz], [bx0, ASHLAR_TOP, bz])
    backing.quad([wx1, 0, bz], [bx1, 0, bz], [bx1, ASHLAR_TOP, bz], [wx1, ASHLAR_TOP, bz])
    backing.quad([wx0, 0, bz], [wx1, 0, bz], [wx1, wy0, bz], [wx0, wy0, bz])
    backing.quad([wx0, wy1, bz], [wx1, wy1, bz], [wx1, ASHLAR_TOP, bz], [wx0, ASHLAR_TOP, bz])

    # The room behind the window, seen through the glass (undisplaced).
    room = Mesh()
    rx0, rx1, ry0, ry1, rz0, rz1 = -2.5, 2.5, 1.4, 4.6, RECESS + 0.02, 3.5
    room.quad([rx0, ry0, rz1], [rx1, ry0, rz1], [rx1, ry1, rz1], [rx0, ry1, rz1])  # back wall
    room.quad([rx0, ry0, rz0], [rx1, ry0, rz0], [rx1, ry0, rz1], [rx0, ry0, rz1])  # floor
    room.quad([rx0, ry1, rz0], [rx1, ry1, rz0], [rx1, ry1, rz1], [rx0, ry1, rz1])  # ceiling
    room.quad([rx0, ry0, rz0], [rx0, ry0, rz1], [rx0, ry1, rz1], [rx0, ry1, rz0])  # left
    room.quad([rx1, ry0, rz0], [rx1, ry0, rz1], [rx1, ry1, rz1], [rx1, ry1, rz0])  # right

    # Parapet above the cornice, and the paving in front of the building.
    parapet, paving = Mesh(), Mesh()
    py0 = prof[-1][0]
    blocks(parapet, py0, py0 + 1.2, 2, 1.2, 2, 2, False)
    for i in range(6):
        za, zb = -0.3 - 0.8 * i, -0.3 - 0.8 * (i + 1)
        paving.quad([x0, 0, za], [x1, 0, za], [x1, 0, zb], [x0, 0, zb], 8, 1,
                    s=(0.0, x1 - x0), t=(0.0, 0.8))
    stone = '"grooves" "float depth" [0.025] "float count" [5] "float gw" [0.3] "float rough" [0.004]'
    # (comment, colour, surface, displacement, bound, mesh); surface None: the default matte.
    return [
        ("Rusticated base: craggy stone", "0.78 0.6 0.42", None,
         '"craggy" "float Km" [0.05] "float freq" [2.5]', "0.15", plinth),
        ("Ashlar: grooved (tooled) stone", "0.86 0.7 0.5", None, stone, "0.035", ashlar),
        ("Cornice", "0.88 0.74 0.54", None,
         '"grooves" "float depth" [0.03] "float count" [4] "float gw" [0.4] "float rough" [0.003]',
         "0.04", cornice),
        ("Windowsill", "0.84 0.68 0.48", None, '"craggy" "float Km" [0.012] "float freq" [6]',
         "0.04", sill),
        ("Window reveal", "0.8 0.64 0.45", None, '"craggy" "float Km" [0.01] "float freq" [5]',
         "0.03", reveal),
        ("Glass: bevelled at each pane's edges, slightly bumpy inside", "0.85 0.9 0.92",
         '"glass" "float eta" [1.5]',
         '"glassbumps" "float Km" [0.006] "float cells" [5] "float bevel" [0.08] "float Kb" [0.012]',
         "0.02", glass),
        ("Parapet", "0.86 0.7 0.5", None, stone, "0.035", parapet),
        ("Paving", "0.6 0.55 0.48", None, '"craggy" "float Km" [0.03] "float freq" [1.5]',
         "0.1", paving),
        ("Backing wall, seen through the joints", "0.45 0.36 0.26", None, None, None, backing),
        ("Room behind the window", "0.35 0.3 0.27", None, None, None, room),
    ]


# Copies of the facade in a street are this far apart along x.
STREET_PITCH = WALL_X[1] - WALL_X[0] + 0.4


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", nargs="?", default="examples/scenes/facade.rib")
    ap.add_argument("--noshadows", action="store_true",
                    help="Plate 3: mark every object invisible to shadow rays")
    ap.add_argument("--mask", action="store_true",
                    help="white where displaced geometry is seen, black elsewhere (measures the "
                         "share of pixels on displaced geometry)")
    ap.add_argument("--copies", type=int, default=1,
                    help="a street of N facades side by side; the camera frames the middle one "
                         "as in facade.rib, the rest of the street is out of view")
    ap.add_argument("--street-view", action="store_true",
                    help="with --copies: stand at the first facade and look down the street, so "
                         "that every copy is in view")
    ap.add_argument("--edge", type=float, default=EDGE, help="subdivision edge length")
    ap.add_argument("--flatness", type=float, default=FLATNESS,
                    help="simplification tolerance (0: off)")
    args = ap.parse_args()

    parts = build_parts()
    per_copy = sum(m.triangles() for *_, m in parts)
    total = per_copy * args.copies
    with open(args.out, "w") as out:
        w = out.write
        if args.copies > 1:
            w("# A street of %d copies of the Plate 2 facade (%d input triangles), %s:\n"
              % (args.copies, total, "seen along the street" if args.street_view else
                 "the middle one framed as in facade.rib"))
            w("# the scaling test of bench/paper/run.sh. Generated by bench/make_facade.py --copies %d%s.\n"
              % (args.copies, " --street-view" if args.street_view else ""))
        else:
            w("# The paper's Plate 2: a sandstone building facade in late-afternoon sun. Grooved ashlar above a\n")
            w("# craggy rusticated base, a cornice, a windowsill and a recessed window of bevelled, bumpy\n")
            w("# glass; %d input triangles, over a million displaced ones. Generated by bench/make_facade.py;\n" % total)
            w("# render with  relief examples/scenes/facade.rib --stats\n")
        if args.noshadows:
            w("# Plate 3: the same scene with no shadows. Every object is marked invisible to shadow rays\n")
            w('# (RenderMan\'s Attribute "visibility" "int transmission" [0]).\n')
        if args.mask:
            w("# Mask variant: white where the camera sees displaced geometry, black elsewhere.\n")
        w('Option "searchpath" "string shader" ["../shaders:&"]\n')
        w("Format 720 480 1\nPixelSamples 1 1\n")
        w('Display "%s" "file" "rgb"\n' % os.path.basename(args.out).replace(".rib", ".png"))
        if args.copies > 1 and args.street_view:
            # Standing on the paving in front of the first facade, looking down the street.
            w('Projection "perspective" "fov" [40]\n')
            w("Rotate -3 1 0 0\nRotate -69 0 1 0\nTranslate 4.0 -1.7 6.0\n")
        else:
            w('Projection "perspective" "fov" [27]\n')
            # Camera a little to the right of the facade, looking slightly left and up at it.
            w("Rotate -2 1 0 0\nRotate 9 0 1 0\nTranslate -1.8 -2.9 12\n")
        w("WorldBegin\n")
        if args.mask:
            w('  LightSource "ambientlight" 1 "intensity" [1]\n')
            w('  Surface "matte" "Ka" [1] "Kd" [0]\n')
        else:
            w('  LightSource "distantlight" 1 "intensity" [1.25] "lightcolor" [1 0.82 0.6]'
              ' "from" [-5 1.9 -2.2] "to" [0 0 0]\n')
            w('  LightSource "ambientlight" 2 "intensity" [0.12]\n')
            w('  Surface "matte"\n')
        if args.noshadows:
            w('  Attribute "visibility" "int transmission" [0]\n')
        w('  Attribute "relief" "float edgelength" [%g] "float flatness" [%g]\n'
          % (args.edge, args.flatness))
        for k in range(args.copies):
            if args.copies > 1:
                offset = k if args.street_view else k - (args.copies - 1) // 2
                w("  # Facade %d of %d\n  TransformBegin\n  Translate %g 0 0\n"
                  % (k + 1, args.copies, offset * STREET_PITCH))
            for comment, color, surface, disp, bound, mesh in parts:
                if args.mask:
                    color, surface = ("1 1 1" if disp else "0 0 0"), None
                w("  # %s\n  AttributeBegin\n    Color [%s]\n" % (comment, color))
                if surface:
                    w("    Surface %s\n" % surface)
                if disp:
                    w('    Attribute "displacementbound" "float sphere" [%s]\n' % bound)
                    w("    Displacement %s\n" % disp)
                w(mesh.rib() + "\n  AttributeEnd\n")
            if args.copies > 1:
                w("  TransformEnd\n")
        w("WorldEnd\n")
    print("%s: %d input triangles" % (args.out, total))


if __name__ == "__main__":
    main()
