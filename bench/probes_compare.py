#!/usr/bin/env python3
"""bench/bench_probes.sh's helper: fills the three.js page and turns the runs into tables.

    python3 bench/probes_compare.py page TEMPLATE THREE_DIR SCENE SKY_POLY GRID CUBES NEAR OUT
    python3 bench/probes_compare.py report WORK

`page` writes OUT, TEMPLATE with its placeholders filled (GRID: JSON {res, min, max}; CUBES: a JSON
list; SCENE "" for the empty scene). `report` reads what bench_probes.sh left in WORK and prints
the Markdown tables of bench/results/probes.md; it exits non-zero when a run is missing or three's
empty-scene bake does not give the sky back.

Conventions. prtbake's probes.npy holds c_i (radiance SH, prtbake's basis with the Condon-Shortley
phase); three's atlas holds k_i = (-1)^m c_i (docs/probes.md "three.js"), so c_i = k_i with
coefficients 1, 3, 5, 7 negated. The error of a probe is the RMS over all normals n (and over
R, G, B) of the difference in irradiance over pi, E/pi(n) = sum_i (A_l/pi) c_i Y_i(n); by the
basis' orthonormality
    rms = sqrt( sum_i (A_l/pi)^2 |dc_i|^2 / (4 pi) / 3 ),
given in % of the open sky's mean E/pi (c_0 Y_0 of the sky, the mean over channels). Probes that
a prtbake run moved out of geometry (or filled) are left out of the statistics (three bakes them
where they stand, inside the object), and counted.
"""
import base64
import json
import math
import os
import re
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import probes_scene  # noqa: E402  the scene's objects, for distances

SIGN = np.array([1, -1, 1, -1, 1, -1, 1, -1, 1], float)  # (-1)^m per coefficient
A_OVER_PI = np.array([1] + [2 / 3] * 3 + [1 / 4] * 5, float)  # A_l / pi
Y0 = 0.28209479177387814


def fill_page(template, three, scene, sky_poly, grid, cubes, near, out):
    text = open(template).read()
    values = {"__THREE__": three, "__SCENE__": scene, "__SKY__": open(sky_poly).read().strip(), "__GRID__": grid,
              "__CUBES__": cubes, "__NEAR__": near}
    for key, value in values.items():
        text = text.replace(key, value)
    open(out, "w").write(text)


def load_npy(path):
    b = open(path, "rb").read()
    n = int.from_bytes(b[8:10], "little")
    header = b[10:10 + n].decode()
    shape = tuple(int(x) for x in re.search(r"\(([^)]*)\)", header).group(1).split(",") if x.strip())
    return np.frombuffer(b[10 + n:], "<f4").reshape(shape).astype(float)


def load_prtbake(d):
    """(coefficients [NZ, NY, NX, 9, 3], excluded mask [NZ, NY, NX], sidecar, time row)."""
    c = load_npy(os.path.join(d, "probes.npy"))
    side = json.load(open(os.path.join(d, "probes.json")))
    bad = np.zeros(c.shape[:3], bool)
    for key in ("moved_probes", "invalid_probes"):
        for p in side["validity"][key]:
            i, j, k = p["index"]
            bad[k, j, i] = True
    wall, peak_kib = open(os.path.join(d, "time.txt")).read().split()[:2]
    return c, bad, side, (float(wall), float(peak_kib) / 1024)


def load_three(path, res):
    text = open(path).read()
    if "RESULT {" not in text:
        sys.exit(f"probes_compare.py: {path}: no result from the page: {text[:2000]}")
    r = json.loads(text.split("RESULT ", 1)[1].splitlines()[0])
    nx, ny, nz = res
    runs = []
    for run in r["runs"]:
        k = np.frombuffer(base64.b64decode(run["k"]), "<f4").astype(float).reshape(nz, ny, nx, 9, 3)
        runs.append((run["cubemapSize"], run["seconds"], k * SIGN[:, None]))
    return r, runs


def rms_error(c, ref):
    """Per probe: RMS over normals and channels of the E/pi difference."""
    d = (c - ref) * A_OVER_PI[:, None]
    return np.sqrt((d ** 2).sum(axis=(-2, -1)) / (4 * math.pi) / 3)


def stats(err, mask, scale):
    e = err[mask] / scale * 100
    return f"{e.mean():.2f} | {np.percentile(e, 95):.2f} | {e.max():.2f}"


def positions(grid):
    res, lo, hi = grid["res"], np.array(grid["min"]), np.array(grid["max"])
    cell = (hi - lo) / np.array(res)
    return [lo[a] + (np.arange(res[a]) + 0.5) * cell[a] for a in range(3)]  # x, y, z


def near_wall_mask(grid, within):
    """Probes of the dark room (x > 0.05, the thin wall's dark face) within `within` of that face."""
    x, y, z = positions(grid)
    m = (x > 0.05) & (x - 0.05 <= within)
    return np.broadcast_to(m[None, None, :], (len(z), len(y), len(x)))


def distance_to_scene(p):
    """(distance, what) from point p to the nearest box of the walls or vertex of the other objects."""
    best = (math.inf, "")
    for name, (lo, hi) in [("the thin wall", probes_scene.THIN_WALL)] + [("the shell", b) for b in probes_scene.SHELL_BOXES]:
        d = np.linalg.norm(np.maximum(np.maximum(np.array(lo) - p, p - np.array(hi)), 0))
        best = min(best, (d, name))
    for name, verts in _object_vertices():
        best = min(best, (np.linalg.norm(verts - p, axis=1).min(), name))
    return best


_VERTS = []


def _object_vertices():
    if not _VERTS:
        _VERTS.extend((name, part[0]) for name, part in probes_scene.scene_objects()[2:])
    return _VERTS


def mean_e(c):
    """Per probe: the mean of E/pi over normals (c_0 Y_0) and E/pi facing the wall (n = -x), channel means."""
    mean = c[..., 0, :].mean(-1) * Y0
    ynx = np.zeros(9)
    ynx[0], ynx[3], ynx[8] = Y0, 0.4886025119029199, 0.5462742152960396  # Y_i(-1, 0, 0), prtbake's basis
    facing = (c * (A_OVER_PI * ynx)[:, None]).sum(-2).mean(-1)
    return mean, facing


def report(work):
    out = []
    sky = np.array(json.load(open(os.path.join(work, "sky.json")))["coefficients"])
    scale = sky[0].mean() * Y0  # the open sky's mean E/pi

    # Sanity: three's bake of the empty scene against the sky's own coefficients.
    grid1 = {"res": [1, 1, 1]}
    _, env_runs = load_three(os.path.join(work, "three_empty.out"), grid1["res"])
    out.append("### Sanity: three.js's bake of an empty scene (the sky alone)\n")
    out.append("One probe, no geometry; three's coefficients converted to prtbake's basis (1, 3, 5, 7 negated) "
               "against the sky's exact SH (`sky.json`). Largest |difference| over the 27 numbers, in % of the "
               "sky's c_0 (channel mean), and the same with three's numbers taken as they are (no sign change):\n")
    out.append("| cube size | converted | unconverted |")
    out.append("|---|---|---|")
    ok = True
    for size, _, c in env_runs:
        conv = np.abs(c[0, 0, 0] - sky).max() / sky[0].mean() * 100
        raw = np.abs(c[0, 0, 0] * SIGN[:, None] - sky).max() / sky[0].mean() * 100
        ok &= conv < 0.5
        out.append(f"| {size} | {conv:.4f} % | {raw:.1f} % |")
    if not ok:
        print("\n".join(out))
        sys.exit("probes_compare.py: three's empty-scene bake does not give the sky back (> 0.5 %)")

    for name, title in (("main", "main"), ("slab", "slab")):
        grid = json.load(open(os.path.join(work, f"{name}_grid.json")))
        res = grid["res"]
        ref, ref_bad, ref_side, _ = load_prtbake(os.path.join(work, f"{name}_ref"))
        cell = (np.array(grid["max"]) - np.array(grid["min"])) / np.array(res)
        near = near_wall_mask(grid, 0.6)
        runs = sorted(int(d.split("_s")[1]) for d in os.listdir(work) if d.startswith(f"{name}_s"))
        _, three_runs = load_three(os.path.join(work, f"three_{name}.out"), res)
        keep = ~ref_bad

        out.append(f"\n### {title}: {res[0]}×{res[1]}×{res[2]} = {int(np.prod(res))} probes over "
                   f"{grid['min']} … {grid['max']} (cell {cell[0]:g} × {cell[1]:g} × {cell[2]:g} m)\n")
        out.append(f"Reference: prtbake --samples {ref_side['parameters']['samples']} "
                   f"({ref_side['samples']['per_probe']} rays per probe, seed 1). Left out: "
                   f"{int((~keep).sum())} probes moved or filled by the reference; "
                   f"{int((keep & near).sum())} of the probes kept are in the dark room within 0.6 m of the thin wall "
                   f"(\"near wall\"). Convergence: the runs below use seed 0, independent of the reference's rotations, "
                   f"so the error of the largest sample count against the reference bounds the reference's own from above.\n")
        out.append("Error per probe: RMS over normals of ΔE/π, % of the open sky's mean E/π. Time: prtbake the whole "
                   "command (`/usr/bin/time` wall; peak RSS), three the bake alone (after a warm-up bake; "
                   "page load, scene load, shader compilation not counted).\n")
        out.append("| baker | setting | time [s] | peak [MiB] | mean | p95 | max | near wall: mean | p95 | max | probes moved |")
        out.append("|---|---|---|---|---|---|---|---|---|---|---|")
        curve = []
        for s in runs:
            c, bad, side, (wall, peak) = load_prtbake(os.path.join(work, f"{name}_s{s}"))
            m = keep & ~bad
            e = rms_error(c, ref)
            curve.append((wall, e[m].mean() / scale * 100, s))
            out.append(f"| prtbake | --samples {s} ({side['samples']['per_probe']} rays) | {wall:.2f} | {peak:.0f} | "
                       f"{stats(e, m, scale)} | {stats(e, m & near, scale)} | {int(bad.sum())} |")
        for size, seconds, c in three_runs:
            e = rms_error(c, ref)
            out.append(f"| three.js | cubemapSize {size} | {seconds:.2f} | – | {stats(e, keep, scale)} | "
                       f"{stats(e, keep & near, scale)} | – |")
        # three's worst probes at its largest cube size, and how close the scene comes to them.
        size, _, c = three_runs[-1]
        e = np.where(keep, rms_error(c, ref), 0)
        x, y, z = positions(grid)
        out.append(f"\nthree's largest errors at cubemapSize {size}, with the distance from the probe to the scene "
                   "(exact to the walls' boxes, to the nearest vertex of the tessellated objects; three's cube camera "
                   "clips what lies nearer than its near plane, 0.1 m):\n")
        for f in np.argsort(e.ravel())[::-1][:3]:
            k, j, i = np.unravel_index(f, e.shape)
            p = np.array([x[i], y[j], z[k]])
            d, what = distance_to_scene(p)
            out.append(f"- probe ({x[i]:g}, {y[j]:g}, {z[k]:g}): {e[k, j, i] / scale * 100:.2f} %; c_0 three "
                       f"{c[k, j, i, 0].mean():.3f}, reference {ref[k, j, i, 0].mean():.3f}; {d:.3f} m from {what}")
        dist = np.array([[[distance_to_scene(np.array([xi, yj, zk]))[0] for xi in x] for yj in y] for zk in z])
        close = keep & (dist < 0.15)
        if not (keep & ~close).any():
            out.append(f"\nAll {int(close.sum())} probes kept lie within 0.15 m of the scene.")
        else:
            out.append(f"\n{int(close.sum())} of the probes kept lie within 0.15 m of the scene. Mean error over those / over "
                       "the others: " + "; ".join(
                           f"{lab} {rms_error(cc, ref)[close].mean() / scale * 100:.2f} % / "
                           f"{rms_error(cc, ref)[keep & ~close].mean() / scale * 100:.2f} %"
                           for lab, cc in [(f"three {sz}", c3) for sz, _, c3 in three_runs] +
                           [("prtbake 256", load_prtbake(os.path.join(work, f"{name}_s256"))[0])]) + ".")
        out.append("")
        for size, seconds, c in three_runs:
            e = rms_error(c, ref)[keep].mean() / scale * 100
            under = [p for p in curve if p[0] <= seconds]
            if under:
                best = min(under, key=lambda p: p[1])
                out.append(f"- three cubemapSize {size}: {seconds:.2f} s, mean error {e:.2f} %; prtbake's best run within "
                           f"that time: --samples {best[2]}, {best[0]:.2f} s, {best[1]:.2f} % "
                           f"({'prtbake closer' if best[1] < e else 'three closer'}).")
            else:
                out.append(f"- three cubemapSize {size}: {seconds:.2f} s, mean error {e:.2f} %; no prtbake run is as fast "
                           f"(fastest {min(p[0] for p in curve):.2f} s).")

        # Leaks: what the dark room's probes next to the thin wall receive.
        out.append(f"\nLeak check, the {int((keep & near).sum())} dark-room probes within 0.6 m of the thin wall: E/π averaged over "
                   "normals, and E/π facing the wall (n = −x), mean and max over those probes (channel means; the "
                   "open sky's mean E/π is " f"{scale:.4f}):\n")
        out.append("| baker | mean E/π: mean | max | facing the wall: mean | max |")
        out.append("|---|---|---|---|---|")
        rows = [("reference (prtbake)", ref)]
        for s in runs:
            if s in (16, 256, max(runs)):
                rows.append((f"prtbake --samples {s}", load_prtbake(os.path.join(work, f"{name}_s{s}"))[0]))
        rows += [(f"three cubemapSize {size}", c) for size, _, c in three_runs]
        m = keep & near
        for label, c in rows:
            mean, facing = mean_e(c)
            out.append(f"| {label} | {mean[m].mean():.5f} | {mean[m].max():.5f} | {facing[m].mean():.5f} | {facing[m].max():.5f} |")

    # The speed line: the 32 x 16 x 32 grid at 256 rays per probe.
    out.append("\n### Speed: 32×16×32 = 16,384 probes, --samples 256, the whole command\n")
    out.append("Three runs each; the row is the run of median wall time (all three walls in brackets), its peak RSS "
               "and its sidecar's timings.\n")
    out.append("| bounces | rays per probe | wall [s] (runs) | peak RSS [MiB] | sidecar total | BVH | surfaces | trace | relocation | moved | invalid |")
    out.append("|---|---|---|---|---|---|---|---|---|---|---|")
    for b in (0, 1):
        runs = sorted((load_prtbake(os.path.join(work, d)) for d in os.listdir(work) if d.startswith(f"speed_b{b}_")),
                      key=lambda r: r[3][0])
        c, bad, side, (wall, peak) = runs[len(runs) // 2]  # the run of median wall time
        t = side["timings_seconds"]
        walls = ", ".join(f"{r[3][0]:.2f}" for r in runs)
        out.append(f"| {b} | {side['samples']['per_probe']} | {wall:.2f} ({walls}) | {peak:.0f} | {t['total']:.2f} | {t['bvh']:.2f} | "
                   f"{t['surfaces']:.2f} | {t['trace']:.2f} | {t['relocation']:.2f} | {side['validity']['moved']} | "
                   f"{side['validity']['invalid']} |")
    print("\n".join(out))


def main():
    if len(sys.argv) >= 2 and sys.argv[1] == "page" and len(sys.argv) == 10:
        fill_page(*sys.argv[2:])
    elif len(sys.argv) == 3 and sys.argv[1] == "report":
        report(sys.argv[2])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
