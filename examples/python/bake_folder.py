"""Bakes a folder of glTF assets for a real-time engine, as a build step would:

  per asset: its per-vertex PRT transport (NAME.transport.npy, order 3, shadowed)
  once:      the engine lighting package of an environment (three.js, Filament, Babylon, glTF)

    /usr/bin/python3 examples/python/bake_folder.py ASSETS_DIR ENVIRONMENT OUT_DIR [--samples N]

Each output is written atomically (a temporary file renamed into place), so that an interrupted
build leaves the previous outputs whole. Assets that fail are reported and the others go on.
"""
import argparse
import os
import pathlib
import sys
import tempfile
from typing import Any

import numpy as np
from numpy.typing import NDArray

import prtbake


def save_atomically(path: pathlib.Path, array: NDArray[Any]) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix="." + path.name + ".")
    try:
        with os.fdopen(fd, "wb") as f:
            np.save(f, array)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("assets", type=pathlib.Path)
    ap.add_argument("environment", type=pathlib.Path)
    ap.add_argument("out", type=pathlib.Path)
    ap.add_argument("--samples", type=int, default=256)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    package = prtbake.ibl(args.environment, args.out / "ibl")
    print("ibl: %d files in %s" % (len(package.files), args.out / "ibl"))
    failed = 0
    for asset in sorted(p for p in args.assets.iterdir() if p.suffix in (".gltf", ".glb")):
        try:
            t = prtbake.transport(asset, samples=args.samples)
        except (prtbake.InputError, ValueError) as e:
            print("skipped %s: %s" % (asset.name, e), file=sys.stderr)
            failed += 1
            continue
        save_atomically(args.out / (asset.stem + ".transport.npy"), t.coeffs)
        print("%s: %d vertices, std. error max %.3g, %.2f s" % (asset.name, t.coeffs.shape[0],
                                                                 t.standard_error_max, t.seconds))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
