"""The lightmap benchmark's scene: a self-shadowing terrain of about 100k triangles with one UV
set (planar: the whole terrain is one chart over [0.02, 0.98]^2) and pillars standing on it,
each face of each pillar its own chart: one OBJ with vt (set 0).

    /usr/bin/python3 bench/lightmap_scene.py OUT.obj [QUADS_PER_SIDE]

Terrain: QUADS_PER_SIDE^2 quads (default 220: 96,800 triangles) over [-10, 10]^2, height
h(x, z) = 0.8 sin(0.9 x) cos(0.7 z) + 0.35 sin(2.3 x + 1.1 z) + 0.15 cos(4.1 z - 0.6 x), y up;
16 square pillars (0.6 wide, 4 tall, 5 faces each: no bottom) whose faces' charts fill the
strip v in [0.002, 0.016] (OBJ's v), apart from the terrain's chart. Normals (vn): the terrain's
from h's gradient, (−∂h/∂x, 1, −∂h/∂z) normalised; the pillars' faces flat. Prints the triangle count.
"""
import math
import sys


def main():
    out = sys.argv[1]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 220
    v, vt, vn, f = [], [], [], []

    def h(x, z):
        return 0.8 * math.sin(0.9 * x) * math.cos(0.7 * z) + 0.35 * math.sin(2.3 * x + 1.1 * z) + 0.15 * math.cos(4.1 * z - 0.6 * x)

    for j in range(n + 1):
        for i in range(n + 1):
            x, z = -10 + 20 * i / n, -10 + 20 * j / n
            v.append((x, h(x, z), z))
            e = 1e-4
            gx, gz = (h(x + e, z) - h(x - e, z)) / (2 * e), (h(x, z + e) - h(x, z - e)) / (2 * e)
            norm = math.sqrt(gx * gx + 1 + gz * gz)
            vn.append((-gx / norm, 1 / norm, -gz / norm))
            vt.append((0.02 + 0.96 * i / n, 0.98 - 0.96 * j / n))  # OBJ's v up
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i + 1
            b, c, d = a + 1, a + n + 2, a + n + 1
            f.append((a, d, c))  # y up: counter-clockwise seen from above (x right, z towards the viewer)
            f.append((a, c, b))
    # Pillars: 4 x 4 of them; each of the 80 faces gets a chart in the bottom strip.
    charts = 80
    k = 0
    for pj in range(4):
        for pi in range(4):
            cx, cz = -7.5 + 5 * pi, -7.5 + 5 * pj
            y0, y1, r = h(cx, cz) - 0.5, h(cx, cz) + 4, 0.3
            corners = [(cx - r, cz - r), (cx + r, cz - r), (cx + r, cz + r), (cx - r, cz + r)]
            faces = []
            for s in range(4):
                (x0, z0), (x1, z1) = corners[s], corners[(s + 1) % 4]
                faces.append([(x0, y0, z0), (x0, y1, z0), (x1, y1, z1), (x1, y0, z1)])  # outward
            faces.append([(x, y1, z) for x, z in reversed(corners)])  # top, facing up
            for quad in faces:
                base = len(v)
                u0, u1 = k / charts + 0.1 / charts, (k + 1) / charts - 0.1 / charts
                uv = [(u0, 0.002), (u1, 0.002), (u1, 0.016), (u0, 0.016)]
                a, b, c = quad[0], quad[1], quad[3]
                e1, e2 = [b[i] - a[i] for i in range(3)], [c[i] - a[i] for i in range(3)]
                n = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
                norm = math.sqrt(sum(x * x for x in n))
                for p, t in zip(quad, uv):
                    v.append(p)
                    vt.append(t)
                    vn.append(tuple(x / norm for x in n))
                f.append((base + 1, base + 2, base + 3))
                f.append((base + 1, base + 3, base + 4))
                k += 1
    with open(out, "w") as o:
        o.write("".join("v %.6f %.6f %.6f\n" % p for p in v))
        o.write("".join("vt %.6f %.6f\n" % t for t in vt))
        o.write("".join("vn %.6f %.6f %.6f\n" % n for n in vn))
        o.write("".join("f %d/%d/%d %d/%d/%d %d/%d/%d\n" % (a, a, a, b, b, b, c, c, c) for a, b, c in f))
    print("triangles", len(f))


main()
