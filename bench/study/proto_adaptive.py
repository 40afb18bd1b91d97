#!/usr/bin/env python3
"""Prototypes of adaptivity *inside* an item's integration domain, judged like `--tolerance`.

The shipped `--tolerance` adapts how many points each vertex/texel gets; oracle.py shows that
on these cases even perfect knowledge of every item's error scale leaves little to gain. These
two prototypes adapt *where* an item's points go instead, with a local error estimate, and are
judged against uniform sampling (the `--samples` path's centred Hammersley set) at the same
maximum error, as criterion (2) of `--tolerance` asks:

- **transport, visibility quadtree** on the open sphere cavity of tests/test_tolerance.cpp
  (radius 1, opening half-angle π/3), whose DC coefficient has a closed form: from any inner
  point the cosine-weighted visible fraction is the opening's share of the sphere's area,
  (1 − cos α)/2; and on vertices of the bumpy sphere of the study (converged reference). The hemisphere is mapped to the unit square by the cosine-weighted map of the
  uniform path; a cell is traced at its four corners (shared with its neighbours); a cell whose
  corners agree counts as fully visible or occluded, a mixed cell is split in four, and the
  estimate counts a mixed cell by its visible corners. The item's error estimate is
  c·Y0·(area of its mixed cells); an item stops when it is below E. Samples = rays traced.
- **LUT, adaptive cubature** on the half-vector domain of lut_reference.cpp (two pieces, each
  mapped to the unit square, GGX, height-correlated Smith). Each cell carries a 3×3
  Gauss–Legendre value and the sum over its four children; the difference is the cell's error
  estimate, and the cell with the largest estimate is split until their sum is below E.
  Samples = integrand evaluations.

Needs python3-numpy. Usage: proto_adaptive.py OUT.md   (about 5 minutes on 2 cores)
"""
import heapq
import math
import sys

import numpy as np

import replay_lut as lut
from oracle import COUNTS as GRID, uniform_per_item

Y0 = 0.28209479177387814


def judged(uniform_max_errors, max_error, mean_cost):
    """Uniform count at max_error ÷ the prototype's mean count per item, as a table cell."""
    n = uniform_per_item(GRID, uniform_max_errors, max_error)
    return "%.2f" % (n / mean_cost) if n < float("inf") else "> %.2f" % (GRID[-1] / mean_cost)


# --- transport: a visibility quadtree --------------------------------------------------------

def tangent_frame(n):
    a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    t = np.cross(n, a)
    t /= np.linalg.norm(t)
    return t, np.cross(n, t)


class Scene:
    """Points with normals; subclasses say which rays are unoccluded and give the reference."""

    def __init__(self, points, normals, seed):
        self.points, self.normals = points, normals
        self.rotations = np.random.default_rng(seed).uniform(0, 2 * math.pi, len(points))  # as the uniform path

    def directions(self, i, u1, u2):
        """Cosine-weighted map of (u1, u2) into point i's hemisphere."""
        t, b = tangent_frame(self.normals[i])
        r, phi = np.sqrt(u1), 2 * math.pi * u2 + self.rotations[i]
        return ((r * np.cos(phi))[..., None] * t + (r * np.sin(phi))[..., None] * b
                + np.sqrt(np.maximum(0, 1 - u1))[..., None] * self.normals[i])

    def uniform(self, i, n):
        """DC coefficient of point i from n centred Hammersley directions (the --samples path)."""
        k = np.arange(n)
        return Y0 * self.visible(i, self.directions(i, (k + 0.5) / n, lut.unit(lut.radinv2(k)))).mean()

    def quadtree(self, i, tol, cells0, c, depth=14):
        """(DC estimate, rays traced) for point i."""
        side = 1 << depth
        seen = {}

        def classify(cells):
            corners = {(x + dx, y + dy) for x, y, s in cells for dx in (0, s) for dy in (0, s)} - seen.keys()
            if corners:
                keys = list(corners)
                u1 = np.clip(np.array([x for x, _ in keys]) / side, 1e-9, 1 - 1e-9)
                vis = self.visible(i, self.directions(i, u1, np.array([y for _, y in keys]) / side))
                seen.update(zip(keys, vis.astype(float)))
            full, mixed = 0.0, []
            for x, y, s in cells:
                v = seen[(x, y)] + seen[(x + s, y)] + seen[(x, y + s)] + seen[(x + s, y + s)]
                if v == 4:
                    full += (s / side) ** 2
                elif v > 0:
                    mixed.append((x, y, s, v / 4))
            return full, mixed

        step = side // cells0
        full, mixed = classify([(x * step, y * step, step) for x in range(cells0) for y in range(cells0)])
        while mixed and c * Y0 * sum((s / side) ** 2 for _, _, s, _ in mixed) >= tol and mixed[0][2] > 1:
            finer = []
            for x, y, s, _ in mixed:
                h = s // 2
                finer += [(x, y, h), (x + h, y, h), (x, y + h, h), (x + h, y + h, h)]
            more, mixed = classify(finer)
            full += more
        return Y0 * (full + sum((s / side) ** 2 * f for _, _, s, f in mixed)), len(seen)


class Cavity(Scene):
    """Inner points of the open sphere cavity; the DC coefficient has a closed form."""

    def __init__(self, points=200, opening=math.pi / 3, seed=1):
        rng = np.random.default_rng(seed)
        self.cos_open = math.cos(opening)
        p = []
        while len(p) < points:   # inner points, away from the rim as in the test
            v = rng.normal(size=3)
            v /= np.linalg.norm(v)
            if v[2] < math.cos(opening + math.pi / 12):
                p.append(v)
        super().__init__(np.array(p), -np.array(p), seed)
        self.reference = np.full(points, Y0 * (1 - self.cos_open) / 2)
        self.reference_bound = 0.0

    def visible(self, i, w):
        """The ray leaves through the opening: its second hit on the sphere is in the cap."""
        p = self.points[i]
        return (p - 2 * (w @ p)[..., None] * w)[..., 2] > self.cos_open


class BumpySphere(Scene):
    """makeBumpySphere(2000) (host/src/mesh.cpp) at randomly chosen vertices; brute-force rays
    against the triangles that rise above the vertex's tangent plane; the reference is 2^16
    Hammersley directions, its bound the change from 2^15."""

    def __init__(self, vertices=60, seed=3):
        rings = int(math.sqrt(2000 / 4.0)) + 1
        segs, pos, start = 2 * rings, [], []
        for i in range(rings + 1):
            th = math.pi * i / rings
            start.append(len(pos))
            for j in range(1 if i in (0, rings) else segs):
                ph = 2 * math.pi * j / segs
                r = 1.0 + 0.18 * math.sin(7 * th) * math.cos(5 * ph) + 0.08 * math.sin(19 * th + 3 * ph)
                pos.append(r * np.array([math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th)]))

        def vid(i, j):
            return start[i] if i in (0, rings) else start[i] + j % segs

        tris = []
        for i in range(rings):
            for j in range(segs):
                a, b, c, d = vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)
                tris += [t for t in ((a, b, c), (a, c, d)) if len(set(t)) == 3]
        pos, tris = np.array(pos), np.array(tris)
        normals = np.zeros_like(pos)
        face = np.cross(pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]])
        for k in range(3):
            np.add.at(normals, tris[:, k], face)
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        chosen = np.random.default_rng(seed).choice(len(pos), vertices, replace=False)
        super().__init__(pos[chosen], normals[chosen], seed)
        self.occluders = []
        for p, n in zip(self.points, self.normals):
            up = ((pos[tris] - p) @ n > 1e-7).any(1)
            v0 = pos[tris[up, 0]]
            self.occluders.append((v0, pos[tris[up, 1]] - v0, pos[tris[up, 2]] - v0))
        self.reference = np.array([self.uniform(i, 1 << 16) for i in range(vertices)])
        self.reference_bound = np.abs(self.reference - [self.uniform(i, 1 << 15) for i in range(vertices)]).max()

    def visible(self, i, w):
        """No occluding triangle within (1e-6, ∞) along the ray (Möller–Trumbore)."""
        v0, e1, e2 = self.occluders[i]
        o = self.points[i] + 1e-4 * self.normals[i]
        out = np.ones(len(w), bool)
        for s in range(0, len(w), 1024):
            d = w[s:s + 1024, None, :]
            pv = np.cross(d, e2[None])
            det = (pv * e1[None]).sum(-1)
            ok = np.abs(det) > 1e-12
            inv = 1 / np.where(ok, det, 1.0)
            tv = (o - v0)[None]
            u = (tv * pv).sum(-1) * inv
            qv = np.cross(tv, e1[None])
            v = (d * qv).sum(-1) * inv
            t = (e2[None] * qv).sum(-1) * inv
            out[s:s + 1024] = ~(ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-6)).any(1)
        return out


def transport_rows(scene, rules):
    items = range(len(scene.points))
    umax = [max(abs(scene.uniform(i, n) - scene.reference[i]) for i in items) for n in GRID]
    rows = []
    for cells0, c in rules:
        for tol in (1e-2, 5e-3, 2e-3, 1e-3):
            res = [scene.quadtree(i, tol, cells0, c) for i in items]
            err = np.abs(np.array([v for v, _ in res]) - scene.reference)
            rays = np.mean([n for _, n in res])
            rows.append("| %d², c = %g | %g | %.3f | %.2e | %.0f | %s |" % (
                cells0, c, tol, (err < tol).mean(), err.max(), rays, judged(umax, err.max(), rays)))
    return rows


# --- LUT: adaptive cubature on the half-vector domain ------------------------------------------

GAUSS = np.polynomial.legendre.leggauss(3)
GX, GW = 0.5 * (GAUSS[0] + 1), 0.5 * GAUSS[1]


def specular(theta, phi, mu, alpha):
    """(A, B) integrands of lut_reference.cpp (GGX, height-correlated Smith) at half vectors."""
    st, ct = np.sin(theta), np.cos(theta)
    sv = math.sqrt(max(0.0, 1 - mu * mu))
    vdoth = sv * st * np.cos(phi) + mu * ct
    nl = 2 * vdoth * ct - mu
    fc = np.clip(1 - vdoth, 0, None) ** 5
    a2 = alpha * alpha
    d = a2 / (math.pi * (st * st + ct * ct * a2) ** 2)
    a_v = math.sqrt(mu * mu * (1 - a2) + a2)
    a_l = np.sqrt(np.maximum(nl, 0) ** 2 * (1 - a2) + a2)
    g = 2 * nl / np.maximum(nl * a_v + mu * a_l, 1e-300)
    v = np.where((nl > 0) & (vdoth > 0), d * g * vdoth * st, 0.0)
    return v * (1 - fc), v * fc


def pieces(mu, alpha):
    """The reference's two smooth pieces of the half-vector domain, each a map of [0, 1]²."""
    theta_v = math.acos(min(max(mu, 0.0), 1.0))
    th1, th2 = max(0.0, math.pi / 4 - theta_v / 2), math.pi / 4 + theta_v / 2

    def x_of(th):
        return 1.0 if th >= math.pi / 2 else 2 / math.pi * math.atan(math.tan(th) / alpha)

    def theta_of(x):
        tau = np.tan(math.pi / 2 * x)
        return np.arctan(alpha * tau), math.pi / 2 * alpha * (1 + tau * tau) / (1 + alpha * alpha * tau * tau)

    x1, x2 = x_of(th1), x_of(th2)
    sv = math.sqrt(max(0.0, 1 - mu * mu))
    out = []
    if x1 > 0:
        def cap(s, t):
            th, dth = theta_of(s * x1)
            a, b = specular(th, t * math.pi, mu, alpha)
            return a * (2 * x1 * dth * math.pi), b * (2 * x1 * dth * math.pi)
        out.append(cap)
    if x2 > x1 and sv > 0:
        def band(s, t):
            h, dh = s * s * (3 - 2 * s), 6 * s * (1 - s)
            th, dth = theta_of(x1 + (x2 - x1) * h)
            phi_max = np.arccos(np.clip(-mu * np.cos(2 * th) / (sv * np.sin(2 * th)), -1, 1))
            a, b = specular(th, t * phi_max, mu, alpha)
            w = 2 * (x2 - x1) * dh * dth * phi_max
            return a * w, b * w
        out.append(band)
    return out


def cell_value(f, s0, t0, h):
    s = s0 + h * GX[:, None] + 0 * GX[None, :]
    t = t0 + h * GX[None, :] + 0 * GX[:, None]
    w = h * h * GW[:, None] * GW[None, :]
    a, b = f(s, t)
    return np.array([(a * w).sum(), (b * w).sum()])


def cubature(mu, alpha, tol, cells0=2):
    """(A, B, integrand evaluations): split the worst cell until the estimates sum below tol."""
    per_cell = len(GX) ** 2
    heap, evals, serial = [], 0, 0

    def push(f, s0, t0, h, value):
        nonlocal evals, serial
        kids = [cell_value(f, s0 + i * h / 2, t0 + j * h / 2, h / 2) for i in (0, 1) for j in (0, 1)]
        evals += 4 * per_cell
        est = np.abs(value - sum(kids)).max()
        heapq.heappush(heap, (-est, serial, f, s0, t0, h, kids))
        serial += 1
        return est

    total = 0.0
    for f in pieces(mu, alpha):
        h = 1 / cells0
        for i in range(cells0):
            for j in range(cells0):
                evals += per_cell
                total += push(f, i * h, j * h, h, cell_value(f, i * h, j * h, h))
    while total >= tol and evals < 1 << 20:
        est, _, f, s0, t0, h, kids = heapq.heappop(heap)
        total += est
        for k, (i, j) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1))):
            total += push(f, s0 + i * h / 2, t0 + j * h / 2, h / 2, kids[k])
    return sum(sum(c[6]) for c in heap), evals


def lut_rows():
    mus, alphas = lut.MU[:, 0], lut.ALPHA[:, 0]
    ref = lut.table(*lut.hammersley(2 ** 18), chunk=4)
    umax = [np.abs(lut.table(*lut.hammersley(n)) - ref).max() for n in GRID]
    rows = []
    for tol in (1e-2, 3e-3, 1e-3, 3e-4, 1e-4):
        res = [cubature(m, a, tol) for m, a in zip(mus, alphas)]
        err = np.abs(np.array([v for v, _ in res]) - ref).max(1)
        evals = np.mean([n for _, n in res])
        rows.append("| 3×3 Gauss cells | %g | %.3f | %.2e | %.0f | %s |" % (
            tol, (err < tol).mean(), err.max(), evals, judged(umax, err.max(), evals)))
    return rows


def main():
    header = ["| rule | E | fraction below E | max error | mean samples per item | uniform ÷ prototype |",
              "|---|---|---|---|---|---|"]
    rules = ((8, 0.15), (16, 0.5), (16, 0.25))
    cav = Cavity()
    md = ["Transport, open sphere cavity (%d inner points, DC coefficient against its closed form); "
          "samples = rays:" % len(cav.points), ""] + header + transport_rows(cav, rules)
    bumpy = BumpySphere()
    md += ["", "Transport, bumpy sphere (%d vertices, DC coefficient; reference bound %.1e); samples = rays:"
           % (len(bumpy.points), bumpy.reference_bound), ""] + header + transport_rows(bumpy, rules)
    md += ["", "LUT, 32² GGX (against 2^18 centred Hammersley points per texel); samples = integrand "
           "evaluations:", ""] + header + lut_rows()
    open(sys.argv[1], "w").write("\n".join(md) + "\n")
    print("wrote", sys.argv[1])


if __name__ == "__main__":
    main()
