"""Per-vertex PRT for the mesh a DCC tool holds, from its arrays: no file in between.

In Blender, `vertex_arrays()` is where the active object's evaluated mesh would be read
(obj.data.vertices.foreach_get("co", ...), loop_triangles' vertices, corner normals) and
`write_back()` where the shade would become a colour attribute; here both work on plain NumPy
arrays so that the script runs, and is tested, anywhere:

    /usr/bin/python3 examples/python/blender_mesh.py [ENVIRONMENT]

It bakes shadowed transport for the mesh, projects the environment (the demo sky by default)
onto SH, and shades every vertex: colour = albedo × Σ_i T_i L_i (docs/conventions.md).
"""
import pathlib
import sys
from typing import Tuple

import numpy as np
from numpy.typing import NDArray

import prtbake


def vertex_arrays() -> Tuple[NDArray[np.float32], NDArray[np.uint32]]:
    """A ground plane with a box standing on it (in Blender: the active object's arrays)."""
    ground = np.array([[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2]], np.float32)
    g = [[0, 2, 1], [0, 3, 2]]
    c = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (0.0, 1.0) for z in (-0.5, 0.5)], np.float32)
    faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    b = []
    for q in faces:
        q = [i + 4 for i in q]
        b += [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
    return np.concatenate([ground, c]), np.array(g + b, np.uint32)


def write_back(colours: NDArray[np.float32]) -> None:
    """In Blender: mesh.color_attributes.new(...).data.foreach_set("color", ...). Here: a summary."""
    print("shaded %d vertices: min %.3f, max %.3f" % (len(colours), colours.min(), colours.max()))


def main() -> None:
    here = pathlib.Path(__file__).resolve().parents[2]
    environment = sys.argv[1] if len(sys.argv) > 1 else str(here / "assets" / "sky.exr")
    positions, triangles = vertex_arrays()
    mesh = prtbake.Mesh(positions, triangles)  # normals: from the faces, as a loader fills them
    transport = prtbake.transport(mesh, samples=512, order=3)
    sky = prtbake.env(environment, order=3)
    # (SH radiance rings below zero near a bright sun: clamped, as a renderer would.)
    colours = np.maximum(transport.coeffs @ sky.coeffs, 0).astype(np.float32) * mesh.albedo
    write_back(colours)


if __name__ == "__main__":
    main()
