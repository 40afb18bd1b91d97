"""Oracle bounds on per-item adaptive sampling, from per-item errors of the uniform path.

Given err[k, i], the error of item i (vertex or texel) at the uniform path's count ns[k],
two idealised stopping rules are set against uniform sampling at the same maximum error:

- the *luck* oracle gives each item the first count whose own error is below E. It knows
  each item's actual error at every count, including where a count happens to land close to
  the answer, which no estimate from the samples can know;
- the *scale* oracle knows each item's error scale s_i (the RMS over counts ≥ 256 of
  err·(N/1024)^a, the truth again) but not the fluctuation about it, and gives each item the
  first count with c·s_i·(1024/N)^a ≤ E; a and c are the best of a small grid, chosen after
  the fact. A real rule also pays for its estimate, so it cannot beat this.

Each ratio is (uniform total at the oracle's maximum error) ÷ (oracle total); above 1, the
oracle is cheaper. Uniform totals are log-log interpolated between the counts in ns.
"""
import math

import numpy as np

COUNTS = [int(round(64 * 2 ** (k / 2))) for k in range(17)]   # uniform counts, 64 .. 16384 (as study.cpp)
ALPHAS = (0.75, 1.0, 1.25, 1.5)
CS = (0.5, 0.7, 1.0, 1.4, 2.0, 2.8, 4.0, 5.6, 8.0)


def uniform_per_item(ns, umax, m):
    """Smallest (interpolated) uniform count whose maximum error is at most m."""
    for a, b, ea, eb in zip(ns, ns[1:], umax, umax[1:]):
        if eb <= m:
            if ea <= m:
                return a
            t = (math.log(ea) - math.log(m)) / (math.log(ea) - math.log(eb))
            return a * (b / a) ** t
    return float("inf")


def ratios(ns, err, tol):
    """(luck ratio, scale ratio) at tolerance tol; err has shape [len(ns), items]."""
    ns = np.asarray(ns, dtype=float)
    items = err.shape[1]
    umax = err.max(1)
    cols = np.arange(items)

    def judged(first):   # first[i]: index into ns for item i
        m = err[first, cols].max()
        return uniform_per_item(list(ns), list(umax), m) * items / ns[first].sum()

    below = err <= tol
    luck = judged(np.where(below.any(0), below.argmax(0), len(ns) - 1))
    best = 0.0
    use = ns >= 256
    for a in ALPHAS:
        scale = np.sqrt(np.mean((err[use] * (ns[use, None] / 1024) ** a) ** 2, 0))
        for c in CS:
            need = 1024 * (c * scale / tol) ** (1 / a)
            best = max(best, judged(np.minimum(np.searchsorted(ns, need), len(ns) - 1)))
    return luck, best


def table(ns, err, tols, what):
    """Markdown rows for the tolerances tols."""
    out = ["| %s | E | luck oracle | scale oracle |" % what, "|---|---|---|---|"]
    for tol in tols:
        luck, scale = ratios(ns, err, tol)
        out.append("| | %g | %.2f | %.2f |" % (tol, luck, scale))
    return out
