#!/usr/bin/env python3
"""The scene and sky of bench/bench_probes.sh: two rooms side by side under a smooth sky.

    python3 bench/probes_scene.py DIR

writes DIR/rooms.gltf + DIR/rooms.bin (the scene, metres, +Y up), DIR/sky.json (the sky's
radiance SH, order 3, in the format `prtbake env` writes) and DIR/sky_poly.json (the same sky as
the polynomial the three.js page evaluates per texel).

The building's inside is x, z in [-4, 4], y in [0, 4], walls and floor 0.2 m thick boxes. A
wall 0.1 m thick (x in [-0.05, 0.05]) splits it into the lit room (x < 0: no ceiling, open to
the sky) and the dark room (x > 0: a ceiling, one 0.8 m x 0.8 m window in its far wall x = 4).
Detail for about 100k triangles: a torus knot and spheres in the lit room, pillars (floor to
ceiling) and spheres in the dark room, one glTF mesh per object (as an asset would be, so that
a rasteriser can cull per object). Every triangle is wound counter-clockwise seen from the side
its outward normal points to (the front face faces open space).

The sky, per linear RGB channel, a polynomial of degree 2 in the direction d = (x, y, z):
    L(d) = s (1 + a y + b x + c z + e (3y^2 - 1)/2 + f x z),
positive everywhere (|a| + |b| + |c| + |e| + |f| < 1), so its order-3 SH projection is exact and
prtbake's SH file and three's per-texel map are the same function.
"""
import json
import math
import os
import struct
import sys

import numpy as np

# Per channel: s, a, b, c, e, f (see the docstring).
SKY = {
    "r": [0.80, 0.45, 0.20, -0.10, 0.10, 0.05],
    "g": [0.90, 0.50, 0.10, 0.05, 0.10, -0.05],
    "b": [1.10, 0.60, -0.15, 0.05, 0.12, 0.02],
}


def sky_radiance(d):
    """d: (..., 3) unit directions -> (..., 3) RGB radiance."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    out = []
    for ch in "rgb":
        s, a, b, c, e, f = SKY[ch]
        out.append(s * (1 + a * y + b * x + c * z + e * (3 * y * y - 1) / 2 + f * x * z))
    return np.stack(out, axis=-1)


def sh9(d):
    """prtbake's basis (docs/conventions.md): real orthonormal SH with the Condon-Shortley phase."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack([
        np.full_like(x, 0.28209479177387814),
        -0.4886025119029199 * y, 0.4886025119029199 * z, -0.4886025119029199 * x,
        1.0925484305920792 * x * y, -1.0925484305920792 * y * z,
        0.31539156525252005 * (3 * z * z - 1), -1.0925484305920792 * x * z,
        0.5462742152960396 * (x * x - y * y)], axis=-1)


def sky_sh():
    """The sky's radiance SH, by a product rule exact for degree 4 (the integrands' degree)."""
    t, w = np.polynomial.legendre.leggauss(16)
    phi = (np.arange(32) + 0.5) * 2 * math.pi / 32
    ct, ph = np.meshgrid(t, phi, indexing="ij")
    st = np.sqrt(1 - ct * ct)
    d = np.stack([st * np.cos(ph), st * np.sin(ph), ct], axis=-1)
    weight = (w[:, None] * np.full_like(ph, 2 * math.pi / 32))[..., None, None]
    return (sh9(d)[..., :, None] * sky_radiance(d)[..., None, :] * weight).sum(axis=(0, 1))  # (9, 3)


# --- geometry: each part is (positions (n, 3), outward normals (n, 3), triangles (m, 3)) ---

def orient(p, n, tri):
    """Winds every triangle counter-clockwise about its vertices' mean outward normal."""
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    flip = (np.cross(b - a, c - a) * (n[tri[:, 0]] + n[tri[:, 1]] + n[tri[:, 2]])).sum(1) < 0
    tri = tri.copy()
    tri[flip] = tri[flip][:, [0, 2, 1]]
    return p, n, tri


def box(lo, hi):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    ps, ns, ts = [], [], []
    for axis in range(3):
        for side in (0, 1):
            u, v = (axis + 1) % 3, (axis + 2) % 3
            q = np.zeros((4, 3))
            q[:, axis] = hi[axis] if side else lo[axis]
            for k, (cu, cv) in enumerate([(0, 0), (1, 0), (1, 1), (0, 1)]):
                q[k, u] = hi[u] if cu else lo[u]
                q[k, v] = hi[v] if cv else lo[v]
            nrm = np.zeros((4, 3))
            nrm[:, axis] = 1 if side else -1
            base = 4 * len(ps)
            ps.append(q), ns.append(nrm), ts.append(np.array([[0, 1, 2], [0, 2, 3]]) + base)
    return orient(np.concatenate(ps), np.concatenate(ns), np.concatenate(ts))


def grid_surface(f, nu, nv, wrap_u, wrap_v):
    """A parametric surface f(u, v) -> (points, normals) on [0, 1]^2, nu x nv quads."""
    cu, cv = nu if wrap_u else nu + 1, nv if wrap_v else nv + 1
    u, v = np.meshgrid(np.arange(cu) / nu, np.arange(cv) / nv, indexing="ij")
    p, n = f(u, v)
    p, n = p.reshape(-1, 3), n.reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    idx = lambda a, b: (a % cu) * cv + (b % cv)
    q00, q10, q11, q01 = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
    tri = np.concatenate([np.stack([q00, q10, q11], -1).reshape(-1, 3), np.stack([q00, q11, q01], -1).reshape(-1, 3)])
    return orient(p, n, tri)


def sphere(c, r, nu=64, nv=32):
    def f(u, v):
        th, ph = math.pi * np.clip(v, 1e-4, 1 - 1e-4), 2 * math.pi * u
        n = np.stack([np.sin(th) * np.cos(ph), np.cos(th), np.sin(th) * np.sin(ph)], -1)
        return np.asarray(c) + r * n, n
    return grid_surface(f, nu, nv, True, False)


def cylinder(c, r, y0, y1, nu=96, nv=24):
    def f(u, v):
        ph = 2 * math.pi * u
        n = np.stack([np.cos(ph), 0 * v, np.sin(ph)], -1)
        p = np.stack([c[0] + r * np.cos(ph), y0 + (y1 - y0) * v, c[1] + r * np.sin(ph)], -1)
        return p, n
    return grid_surface(f, nu, nv, True, False)


def torus_knot(c, radius, tube, p=2, q=3, nu=1024, nv=24):
    def curve(t):
        a = 2 * math.pi * t
        rr = radius * (2 + np.cos(q * a)) / 3
        return np.stack([rr * np.cos(p * a), radius * np.sin(q * a) / 3, rr * np.sin(p * a)], -1)

    def f(u, v):
        k0, k1 = curve(u), curve(u + 1e-4)
        tang = k1 - k0
        tang /= np.linalg.norm(tang, axis=-1, keepdims=True)
        ref = np.broadcast_to(np.array([0.0, 1.0, 0.0]), tang.shape)
        b = np.cross(tang, ref)
        b /= np.linalg.norm(b, axis=-1, keepdims=True)
        nn = np.cross(b, tang)
        a = 2 * math.pi * v
        n = np.cos(a)[..., None] * nn + np.sin(a)[..., None] * b
        return np.asarray(c) + k0 + tube * n, n
    return grid_surface(f, nu, nv, True, True)


def merge(parts):
    ps, ns, ts, base = [], [], [], 0
    for p, n, t in parts:
        ps.append(p), ns.append(n), ts.append(t + base)
        base += len(p)
    return np.concatenate(ps), np.concatenate(ns), np.concatenate(ts)


W, T, H = 4.0, 0.2, 4.0  # half-width of the inside, outer wall thickness, wall height
SHELL_BOXES = [
    ([-W - T, -T, -W - T], [W + T, 0, W + T]),  # floor
    ([-W - T, 0, -W - T], [-W, H, W + T]),      # west wall (lit room)
    ([-W, 0, -W - T], [W, H, -W]),              # north wall
    ([-W, 0, W], [W, H, W + T]),                # south wall
    ([0, H, -W - T], [W + T, H + T, W + T]),    # the dark room's ceiling
    # the east wall (the dark room's far wall) around its window: y 2 .. 2.8, z -0.4 .. 0.4
    ([W, 0, -W - T], [W + T, 2.0, W + T]),
    ([W, 2.8, -W - T], [W + T, H, W + T]),
    ([W, 2.0, -W - T], [W + T, 2.8, -0.4]),
    ([W, 2.0, 0.4], [W + T, 2.8, W + T]),
]
THIN_WALL = ([-0.05, 0, -W], [0.05, H, W])


def scene_objects():
    """(name, part) per glTF mesh."""
    objects = [("shell", merge([box(lo, hi) for lo, hi in SHELL_BOXES])), ("thin_wall", box(*THIN_WALL))]
    objects.append(("knot", torus_knot([-2.0, 1.7, 0.0], 1.3, 0.22)))
    for k, (x, z, r) in enumerate([(-3.2, -3.2, 0.45), (-3.2, 3.1, 0.5), (-0.8, -3.0, 0.4), (-0.9, 3.0, 0.45)]):
        objects.append((f"lit_sphere{k}", sphere([x, r, z], r)))
    for k, (x, z) in enumerate([(1.3, -1.6), (1.3, 1.6), (2.8, -1.6), (2.8, 1.6)]):
        objects.append((f"pillar{k}", cylinder([x, z], 0.25, 0.0, H)))
    for k, (x, z, r) in enumerate([(2.0, -3.2, 0.5), (2.0, 3.2, 0.5), (3.3, 0.0, 0.4), (0.8, 0.0, 0.45)]):
        objects.append((f"dark_sphere{k}", sphere([x, r, z], r)))
    return objects


def write_gltf(path_gltf, objects):
    blob, views, accessors, meshes, nodes = bytearray(), [], [], [], []

    def add(array, target, comp):
        data = array.astype("<f4" if comp == 5126 else "<u4").tobytes()
        while len(blob) % 4:
            blob.append(0)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data), "target": target})
        blob.extend(data)
        acc = {"bufferView": len(views) - 1, "componentType": comp, "count": int(array.shape[0]),
               "type": "VEC3" if array.ndim == 2 else "SCALAR"}
        if comp == 5126:
            acc["min"], acc["max"] = array.min(0).tolist(), array.max(0).tolist()
        accessors.append(acc)
        return len(accessors) - 1

    triangles = 0
    for name, (p, n, t) in objects:
        pos, nrm = add(p, 34962, 5126), add(n / np.linalg.norm(n, axis=1, keepdims=True), 34962, 5126)
        ind = add(t.reshape(-1), 34963, 5125)
        meshes.append({"name": name, "primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm}, "indices": ind, "material": 0}]})
        nodes.append({"name": name, "mesh": len(meshes) - 1})
        triangles += len(t)
    bin_name = os.path.splitext(os.path.basename(path_gltf))[0] + ".bin"
    gltf = {
        "asset": {"version": "2.0", "generator": "prtbake bench/probes_scene.py"},
        "scene": 0, "scenes": [{"nodes": list(range(len(nodes)))}], "nodes": nodes, "meshes": meshes,
        "materials": [{"name": "grey", "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.6, 0.6, 1], "metallicFactor": 0}}],
        "accessors": accessors, "bufferViews": views, "buffers": [{"uri": bin_name, "byteLength": len(blob)}],
    }
    with open(os.path.join(os.path.dirname(path_gltf), bin_name), "wb") as f:
        f.write(blob)
    with open(path_gltf, "w") as f:
        json.dump(gltf, f)
    return triangles


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    triangles = write_gltf(os.path.join(out, "rooms.gltf"), scene_objects())
    coeffs = sky_sh()
    with open(os.path.join(out, "sky.json"), "w") as f:
        json.dump({"order": 3, "quantity": "radiance", "coefficients": coeffs.tolist(),
                   "conventions": {"basis": "real orthonormal spherical harmonics with the Condon-Shortley phase",
                                   "source": "bench/probes_scene.py: the degree-2 sky polynomial, projected exactly"}}, f, indent=1)
    with open(os.path.join(out, "sky_poly.json"), "w") as f:
        json.dump(SKY, f)
    print(f"triangles {triangles}")


if __name__ == "__main__":
    main()
