#!/usr/bin/env python3
"""Offline replay of `--tolerance` stopping rules on a 32² GGX split-sum table.

Every texel is integrated to 16384 points by several point sequences; every stopping rule
is then replayed on the saved prefix means, and each rule's total sample count is set
against the uniform sample count (centred Hammersley, the `--samples` path) that reaches
the same maximum error. Writes bench/results/study/replay_lut.md (read by make_report.py).

The estimator is a NumPy port of lut.cl (GGX, height-correlated Smith, visible-normal
sampling, polar disk mapping); at 16384 Hammersley points it matches the kernel's table to
1.4e-5 (float accumulation in the kernel). The reference is the same estimator with 2^18
centred Hammersley points; its bound is its largest change from 2^17 points (1.5e-5), and it
agrees with computeLutReference (Gauss–Legendre, double) to 1.5e-5.

Needs python3-numpy. Usage: replay_lut.py OUT.md   (about a minute on 2 cores)
Also writes the oracle bounds of oracle.py for the centred Hammersley table.
"""
import math
import sys

import numpy as np

from oracle import COUNTS, table as oracle_table

S = 32                                   # table size (texels per axis)
NS = [2 ** k for k in range(4, 15)]      # prefix lengths 16 .. 16384
MU = np.tile((np.arange(S) + 0.5) / S, S)[:, None]            # texel t = row·S + col
ALPHA = np.repeat(((np.arange(S) + 0.5) / S) ** 2, S)[:, None]  # α = roughness²


def weights(u1, u2, mu, alpha):
    """Per-sample A and B weights of lut.cl for points (u1, u2) and texels (μ, α)."""
    sv = np.sqrt(np.maximum(1 - mu * mu, 0))
    vsx, vsz = alpha * sv, mu
    vlen = 1 / np.sqrt(vsx * vsx + vsz * vsz)
    vhx, vhz = vsx * vlen, vsz * vlen
    s = 0.5 * (1 + vhz)
    a2 = alpha * alpha
    a_v = np.sqrt(mu * mu * (1 - a2) + a2)
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    t1, t2r = r * np.cos(phi), r * np.sin(phi)
    t1sq = t1 * t1
    c2 = np.maximum(1 - t1sq, 0)
    t2 = (1 - s) * np.sqrt(c2) + s * t2r
    nw = np.sqrt(np.maximum(c2 - t2 * t2, 0))
    nx = nw * vhx - t2 * vhz
    nz = np.maximum(t2 * vhx + nw * vhz, 0)
    inv = 1 / np.sqrt(a2 * (nx * nx + t1sq) + nz * nz)
    vdoth = (sv * alpha * nx + mu * nz) * inv
    nl = 2 * vdoth * nz * inv - mu
    fc = np.clip(1 - vdoth, 0, 1) ** 5
    a_l = np.sqrt(nl * nl * (1 - a2) + a2)
    g = np.where(nl > 0, nl / np.maximum(nl * a_v + mu * a_l, 1e-30), 0.0) * (mu + a_v)
    return g - g * fc, g * fc


def radinv2(i):
    i = np.asarray(i, dtype=np.uint64) & 0xFFFFFFFF
    i = ((i << 16) | (i >> 16)) & 0xFFFFFFFF
    for m, sh in ((0x00FF00FF, 8), (0x0F0F0F0F, 4), (0x33333333, 2), (0x55555555, 1)):
        i = ((i & m) << sh) | ((i >> sh) & m)
    return i


def sobol2(i):
    """Second Sobol' dimension (Pascal matrix mod 2), as in host/src/sobol.h."""
    i = np.asarray(i, dtype=np.uint64).copy()
    r, v = np.zeros_like(i), np.full_like(i, 1 << 31)
    while np.any(i):
        r ^= np.where(i & 1, v, 0)
        i >>= 1
        v ^= v >> 1
    return r


def owen(x, seed):
    """Hash-based nested uniform scramble (Burley 2020, Laine–Karras permutation)."""
    x = radinv2(x)
    x = (x + seed) & 0xFFFFFFFF
    for c in (0x6C50B47C, 0xB82F1E52, 0xC7AFE638, 0x8D22F6E6):
        x ^= (x * c) & 0xFFFFFFFF
    return radinv2(x)


def mix(x):
    x = np.asarray(x, dtype=np.uint64)
    x ^= x >> 16
    x = (x * 0x7FEB352D) & 0xFFFFFFFF
    x ^= x >> 15
    x = (x * 0x846CA68B) & 0xFFFFFFFF
    return x ^ (x >> 16)


def unit(x):
    return x.astype(np.float64) * 2.0 ** -32


def prefix_means(u1, u2, ns, chunk=64):
    """{N: (A, B) mean of the first N points} for every texel and every N in ns; the
    points u1, u2 are shared (1-D) or per texel (2-D)."""
    out = {n: np.zeros((S * S, 2)) for n in ns}
    for c0 in range(0, S * S, chunk):
        t = slice(c0, c0 + chunk)
        p1 = u1[None, :] if u1.ndim == 1 else u1[t]
        p2 = u2[None, :] if u2.ndim == 1 else u2[t]
        wa, wb = weights(p1[:, :max(ns)], p2[:, :max(ns)], MU[t], ALPHA[t])
        ca, cb = np.cumsum(wa, 1), np.cumsum(wb, 1)
        for n in ns:
            out[n][t] = np.stack([ca[:, n - 1] / n, cb[:, n - 1] / n], 1)
    return out


def table(u1, u2, chunk=64):
    """(A, B) means over all points, for every texel."""
    return prefix_means(u1, u2, [u1.shape[-1]], chunk)[u1.shape[-1]]


def hammersley(n):
    k = np.arange(n)
    return (k + 0.5) / n, unit(radinv2(k))


def faure_centred(n_max):
    """2-D Faure (0,2)-sequence in base 3 with the digital shift 0.111…₃ = 1/2: every
    prefix of 3^m points sits at the centres of its elementary intervals."""
    digits = 12
    k = np.arange(n_max)
    a = np.stack([(k // 3 ** j) % 3 for j in range(digits)], 1)
    pascal = np.array([[math.comb(j, i) % 3 for j in range(digits)] for i in range(digits)])
    scale = 3.0 ** -(np.arange(digits) + 1)
    u1 = (((a + 1) % 3) * scale).sum(1) + 0.5 * 3.0 ** -digits
    u2 = ((((a @ pascal.T) % 3 + 1) % 3) * scale).sum(1) + 0.5 * 3.0 ** -digits
    return u1, u2


def main():
    out_path = sys.argv[1]
    ref = table(*hammersley(2 ** 18), chunk=4)
    ref_bound = np.abs(ref - table(*hammersley(2 ** 17), chunk=8)).max()

    def err(x):
        return np.abs(x - ref).max(1)

    k = np.arange(NS[-1], dtype=np.uint64)
    d0, d1 = radinv2(k), sobol2(k)
    texel = np.arange(S * S, dtype=np.uint64)[:, None]
    seq = {
        "hammersley": {n: table(*hammersley(n)) for n in NS},
        "sobol": prefix_means(unit(d0 ^ 0xAAAAAAAA), unit(d1), NS),
        "owen": prefix_means(unit(owen(d0[None, :], mix(4 * texel))), unit(owen(d1[None, :], mix(4 * texel + 1))), NS),
        "owen2": prefix_means(unit(owen(d0[None, :], mix(4 * texel + 2))), unit(owen(d1[None, :], mix(4 * texel + 3))), NS),
    }
    fu1, fu2 = faure_centred(3 ** 9)
    faure_ns = [3 ** j for j in range(4, 10)]
    faure = prefix_means(fu1, fu2, faure_ns)

    um = {n: err(seq["hammersley"][n]).max() for n in NS}

    def uniform_total(m):
        """Centred Hammersley samples (total) for maximum error m, log-log interpolated."""
        for a, b in zip(NS, NS[1:]):
            if um[b] <= m:
                if um[a] <= m:
                    return a * S * S
                t = (math.log(um[a]) - math.log(m)) / (math.log(um[a]) - math.log(um[b]))
                return a * (b / a) ** t * S * S
        return float("inf")

    nbr = []
    for t in range(S * S):
        c, r = t % S, t // S
        nbr.append([rr * S + cc for rr in (r - 1, r, r + 1) for cc in (c - 1, c, c + 1) if 0 <= rr < S and 0 <= cc < S])

    def replay(name, k_factor, tol, pool):
        """Stops each texel at the first N ≥ 256 whose estimate is below tol."""
        stop = np.full(S * S, NS[-1])
        done = np.zeros(S * S, bool)
        for n in NS:
            if n < 64:
                continue
            if name == "pair":   # two scrambles of n/2 points each; estimate |A − B|/2
                half = n // 2
                a = np.abs(seq["owen"][half] - seq["owen2"][half]).max(1) / 2
                b = np.abs(seq["owen"][half // 2] - seq["owen2"][half // 2]).max(1) / 2
            else:                # prefix (or restart) differences
                s = seq[name]
                a = np.abs(s[n] - s[n // 2]).max(1)
                b = np.abs(s[n // 2] - s[n // 4]).max(1)
            x = np.maximum(a, b / 2)
            if pool == "rms":
                x = np.array([math.sqrt(np.mean(x[v] ** 2)) for v in nbr])
            elif pool == "max":
                x = np.array([x[v].max() for v in nbr])
            new = (~done) & (k_factor * x < tol) & (n >= 256)
            stop[new] = n
            done |= new
        if name == "pair":
            val = np.stack([(seq["owen"][n // 2][t] + seq["owen2"][n // 2][t]) / 2 for t, n in enumerate(stop)])
        else:
            val = np.stack([seq[name][n][t] for t, n in enumerate(stop)])
        # A restart evaluates every level's fresh set: 64 + 128 + … + N points.
        cost = np.where(stop > 0, 2 * stop - 64, stop) if name == "hammersley" else stop
        e = err(val)
        return (e < tol).mean(), e.max(), cost.sum(), uniform_total(e.max())

    md = []
    w = md.append
    w("Reference: 2^18 centred Hammersley points per texel (bound %.1e, its largest change from 2^17)." % ref_bound)
    w("")
    w("Integration error (max / mean over the 1024 texels) of N points:")
    w("")
    w("| N | centred Hammersley | Sobol' prefix (1010… shift) | Owen-scrambled Sobol' prefix, per texel |")
    w("|---|---|---|---|")
    for n in NS[2:]:
        w("| %d | %s |" % (n, " | ".join("%.1e / %.1e" % (err(seq[s][n]).max(), err(seq[s][n]).mean())
                                          for s in ("hammersley", "sobol", "owen"))))
    w("")
    w("Centred base-3 Faure prefixes (the 0.111…₃ shift puts every 3^m prefix at its cells' centres): " +
      ", ".join("N = %d: %.1e / %.1e" % (n, err(faure[n]).max(), err(faure[n]).mean()) for n in faure_ns) + ".")
    w("")
    oracle = []
    sobol_err = {n: err(seq["sobol"][n]) for n in NS}
    for tol in (3e-3, 1e-3, 3e-4):
        stop = np.full(S * S, NS[-1])
        for n in reversed(NS[2:]):
            stop = np.where(sobol_err[n] <= tol, n, stop)
        final = np.array([sobol_err[n][t] for t, n in enumerate(stop)])
        oracle.append("E = %g: %.2fx" % (tol, uniform_total(final.max()) / stop.sum()))
    w("An oracle that stops each texel's Sobol' prefix at the first N whose true error is below E needs "
      "fewer samples than uniform sampling at the same maximum error by " + ", ".join(oracle) + ".")
    w("")
    grid = COUNTS
    gerr = np.array([err(seq["hammersley"][n] if n in seq["hammersley"] else table(*hammersley(n))) for n in grid])
    w("Oracle bounds (bench/study/oracle.py) from the centred Hammersley table at %d counts from %d to %d:"
      % (len(grid), grid[0], grid[-1]))
    w("")
    md.extend(oracle_table(grid, gerr, (1e-2, 3e-3, 1e-3, 3e-4, 1e-4), "table"))
    w("")
    w("Stopping rules replayed (estimate K·max(d(N), d(N/2)/2), stop at the first N ≥ 256 below E; pooled: "
      "the RMS or maximum of that quantity over the texel's 3×3 neighbourhood). Each cell: fraction of texels "
      "below E / (uniform total at equal maximum error ÷ adaptive total); above 1 means adaptive is cheaper.")
    w("")
    tols = (1e-2, 3e-3, 1e-3, 3e-4)
    w("| points | pooling | K | " + " | ".join("E = %g" % t for t in tols) + " |")
    w("|---|---|---|" + "---|" * len(tols))
    labels = {"sobol": "Sobol' prefix (shared)", "owen": "Owen-scrambled prefix (per texel)",
              "pair": "two Owen scrambles (per texel)", "hammersley": "fresh centred Hammersley per doubling"}
    for name in ("sobol", "owen", "pair", "hammersley"):
        for pool in ("self", "rms", "max"):
            for kf in (1, 2):
                cells = []
                for tol in tols:
                    frac, _, tot, ut = replay(name, kf, tol, pool)
                    cells.append("%.3f / %.2f" % (frac, ut / tot))
                w("| %s | %s | %g | %s |" % (labels[name], pool, kf, " | ".join(cells)))
    open(out_path, "w").write("\n".join(md) + "\n")
    print("wrote", out_path)


if __name__ == "__main__":
    main()
