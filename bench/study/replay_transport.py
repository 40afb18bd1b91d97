#!/usr/bin/env python3
"""Oracle bounds (oracle.py) for `--tolerance` on the bumpy sphere (shadowed, order 3).

Reads bench/results/study/transport_pervertex.txt, written by the study: one line per
uniform count N ("N e_0 e_1 …", the default sampler on a 2^(1/2) grid from 64 to 16384),
e_i the largest coefficient error of vertex i against the study's converged reference.
Writes OUT.md (read by make_report.py). Needs python3-numpy.

Usage: replay_transport.py PERVERTEX.txt OUT.md
"""
import sys

import numpy as np

from oracle import table


def main():
    rows = [line.split() for line in open(sys.argv[1]) if line.strip()]
    ns = [int(r[0]) for r in rows]
    err = np.array([[float(x) for x in r[1:]] for r in rows])
    md = ["Bumpy sphere, shadowed (%d vertices), default sampler at %d counts from %d to %d:" % (
        err.shape[1], len(ns), ns[0], ns[-1]), ""]
    md += table(ns, err, (1e-2, 5e-3, 2e-3, 1e-3), "case")
    open(sys.argv[2], "w").write("\n".join(md) + "\n")
    print("wrote", sys.argv[2])


if __name__ == "__main__":
    main()
