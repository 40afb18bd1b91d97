"""prtbake: SH lighting, PRT transport, BRDF tables and prefiltered environments on OpenCL.

Each product is one call with NumPy arrays in and out:

    import prtbake
    sky = prtbake.env("sky.exr", order=3)                 # sky.coeffs: (9, 3) float64
    t = prtbake.transport("statue.glb", samples=256)      # t.coeffs: (V, 9) float32
    shade = t.coeffs @ sky.coeffs                          # (V, 3): exit radiance / albedo

A product's keywords are its options as the command line and job files know them
(`--bounce-tolerance` is `bounce_tolerance=`), with the same defaults, ranges and checks: they
come from the one declaration of each product's options (`prtbake keys`, docs/jobs.md).
`device=` picks the OpenCL device ("cpu", "gpu", an index; default $PRTBAKE_DEVICE or auto);
`progress=` takes a function progress(stage, fraction). Ctrl-C stops a call within a second.
The conventions (SH basis and order, cube faces, lat-long axes, units) are docs/conventions.md's.

Errors: a bad parameter is a ValueError; a missing or malformed input a prtbake.InputError;
an OpenCL failure a prtbake.DeviceError; a failed write a prtbake.OutputError. The message is
the command line's: the subject (file or option) and what is wrong with it.
"""
from __future__ import annotations

import inspect as _inspect
from typing import Any, Dict, List, Optional, Tuple

import numpy as _np

from . import _prtbake
from ._prtbake import (DeviceError, Error, InputError, Mesh, OutputError, __version__, devices, preview_env,
                       preview_lightmap, preview_lut, preview_mesh, preview_prefilter, read_exr, rotate, run)

__all__ = ["env", "rotate", "transport", "glossy", "lut", "prefilter", "ibl", "probes", "lightmap", "run", "devices", "read_exr",
           "preview_env", "preview_mesh", "preview_lightmap", "preview_lut", "preview_prefilter",
           "keywords", "Mesh", "Error", "InputError", "DeviceError", "OutputError", "EnvResult",
           "TransportResult", "GlossyResult", "LutResult", "PrefilterResult", "IblResult", "ProbeGridResult", "LightmapResult",
           "RunResult"]


class _Result:
    """A product's result: its arrays and figures as attributes."""

    def __init__(self, **fields: Any) -> None:
        self.__dict__.update(fields)

    def __repr__(self) -> str:
        def short(v: Any) -> str:
            if isinstance(v, _np.ndarray):
                return "array(%s, %s)" % (v.shape, v.dtype)
            return repr(v) if not isinstance(v, list) or len(v) < 6 else "[%d items]" % len(v)
        return "%s(%s)" % (type(self).__name__, ", ".join("%s=%s" % (k, short(v)) for k, v in vars(self).items()))


class EnvResult(_Result):
    """SH coefficients of an environment (index l(l+1)+m, columns R, G, B)."""
    coeffs: _np.ndarray            # (n², 3) float64, the quantity asked, windowed
    radiance: _np.ndarray          # (n², 3) float64, unwindowed radiance
    order: int
    quantity: str
    window_weights: List[float]    # w_l, l = 0..n-1
    order_selection: Optional[Dict[str, Any]]  # order="auto": what was chosen and why
    layout: str
    width: int
    height: int
    texels: int
    clamped_texels: int
    kernel_seconds: float
    seconds: float


class TransportResult(_Result):
    """Per-vertex transport T_i(p) (docs/conventions.md "Transport")."""
    coeffs: _np.ndarray            # (V, n²) float32, or (V, 3, n²) for coloured interreflection
    standard_error: _np.ndarray    # (V,) float32, of the direct term
    order: int
    channels: int
    samples: int
    rays: int
    bounces_used: int
    standard_error_max: float
    standard_error_mean: float
    vertices_unoccludable: int
    samples_total: int
    seconds: float
    device: str


class GlossyResult(_Result):
    """Per-vertex glossy transfer matrices (docs/glossy.md)."""
    matrices: _np.ndarray          # (V, [3,] n_out², n_in²) float32 or float16 (dtype=)
    order_out: int
    order_in: int
    channels: int
    samples: int
    rays: int
    standard_error_max: float
    standard_error_mean: float
    bounces_used: int
    seconds: float
    cpca: Optional[Dict[str, Any]]  # with cpca_clusters or cpca_error: means, basis, cluster_of, weights, ...


class LutResult(_Result):
    """Split-sum BRDF tables, row = roughness (row 0: r = 0), column = N·V (docs/lut.md)."""
    a: _np.ndarray                 # (N, N) float32, scale of F0
    b: _np.ndarray                 # (N, N) float32, bias
    third: Optional[_np.ndarray]   # multiscatter E or cloth (N, N)
    e: Optional[_np.ndarray]       # Kulla-Conty E (N, N)
    e_avg: Optional[_np.ndarray]   # Kulla-Conty Eavg (N,)
    size: int
    samples_total: int
    standard_error_max: float
    standard_error_mean: float
    seconds: float
    device: str


class PrefilterResult(_Result):
    """A prefiltered specular cube chain: level k is (6, n_k, n_k, 3) float32, faces +X, -X, +Y, -Y, +Z, -Z."""
    levels: List[_np.ndarray]
    roughness: List[float]
    alpha: List[float]
    error: List[Dict[str, float]]  # each level's estimated relative error: mean, p99, max
    seconds: float
    device: str


class LightmapResult(_Result):
    """A lightmap (docs/lightmap.md): per-texel products on the mesh's UV set, row 0 at v = 0."""
    ao: Optional[_np.ndarray]          # (H, W) float32, cosine-weighted visibility (None: not asked for)
    bent: Optional[_np.ndarray]        # (H, W, 3) float32, unit bent normals, object space
    bent_tangent: Optional[_np.ndarray]  # (H, W, 3) float32, the same in tangent space (meshes with glTF tangents)
    irradiance: Optional[_np.ndarray]  # (H, W, 3) float32, E/pi, linear RGB
    transport: Optional[_np.ndarray]   # (H, W, n²) or (H, W, 3, n²) float32, per-texel PRT transport
    sh: Optional[_np.ndarray]          # (H, W, m², 3) float32, directional irradiance: E(n')/pi = sum_j sh[..., j, :] Y_j(n')
    sh_order: int                      # m: 2 (L1) or 3 (L2); 0 without sh
    state: _np.ndarray                 # (H, W) uint8: 0 empty, 1 baked, 2 moved, 3 buried, 4 dilated
    uv_set: int
    order: int
    baked: int
    moved: int
    buried: int
    dilated: int
    charts: int
    seam_edges: int
    samples: int
    rays: int
    seconds: float
    device: str


class ProbeGridResult(_Result):
    """A light probe grid (docs/probes.md): radiance SH at each probe, probes at cell centres."""
    coeffs: _np.ndarray            # (NZ, NY, NX, n², 3) float32, linear RGB radiance coefficients
    positions: _np.ndarray         # (NZ, NY, NX, 3) float32, where each probe was baked
    state: _np.ndarray             # (NZ, NY, NX) uint8: 0 valid, 1 moved, 2 invalid (filled)
    backface_fraction: _np.ndarray # (NZ, NY, NX) float32
    resolution: Tuple[int, int, int]
    bounds_min: Tuple[float, float, float]
    bounds_max: Tuple[float, float, float]
    order: int
    moved: int
    invalid: int
    samples: int
    rays: int
    seconds: float
    device: str


class IblResult(_Result):
    """An engine lighting package written to a directory."""
    files: List[str]
    radiance: _np.ndarray          # (9, 3) float64, the coefficients every SH export is made from
    seconds: float


class RunResult(_Result):
    """What a run of job files did."""
    ok: int
    skipped: int
    failed: int
    bad_files: int
    seconds: float


def keywords() -> Dict[str, List[tuple]]:
    """Each product's keywords: {product: [(name, kind, default, values, meaning)]}, from the one declaration.

    kind: integer, integer_or_auto, number, boolean, choice, choice_list, path or number_list."""
    return _prtbake.keywords()


_SUMMARY = {
    "env": ("source", "SH coefficients of an environment.\n\n"
            "source: a file (OpenEXR, .hdr, .png/.jpg cross or lat-long) or a directory of six faces, or an\n"
            "array: (H, 2H, 3) lat-long or (6, N, N, 3) cube faces of linear RGB radiance (float32 is read\n"
            "as it is, other dtypes converted once). Returns EnvResult."),
    "transport": ("mesh", "Per-vertex PRT transport of a mesh.\n\n"
                  "mesh: a prtbake.Mesh (from arrays or Mesh.load) or the path of a .gltf, .glb or .obj file.\n"
                  "Returns TransportResult; coeffs @ environment radiance coefficients gives the exit radiance\n"
                  "divided by the albedo."),
    "glossy": ("mesh", "Per-vertex glossy transfer matrices, optionally with an exit-radiance BRDF and CPCA.\n\n"
               "mesh: a prtbake.Mesh or a mesh file. Returns GlossyResult."),
    "lut": (None, "Split-sum BRDF lookup tables. Returns LutResult."),
    "prefilter": ("source", "Prefiltered specular cube chain of an environment (a file or an array, as env).\n\n"
                  "Returns PrefilterResult."),
    "probes": ("scene", "A light probe grid: radiance SH at points in space, for moving objects.\n\n"
               "scene: a prtbake.Mesh or a mesh file. env: an SH JSON or environment map path, or radiance\n"
               "coefficients as an (n², 3) array (an EnvResult's coeffs). Returns ProbeGridResult."),
    "lightmap": ("mesh", "Per-texel AO, bent normals, irradiance, directional (SH) irradiance and transport\non a mesh's lightmap UVs.\n\n"
                 "mesh: a prtbake.Mesh (with uvs) or a mesh file. env: an SH JSON or environment map path, or\n"
                 "radiance coefficients as an (n², 3) array. Returns LightmapResult."),
    "ibl": ("source", "Engine lighting packages (three.js, Filament, Babylon.js, glTF) written to out_dir,\n"
            "which appears whole or not at all. Returns IblResult."),
}


def _product(name: str) -> Any:
    first, summary = _SUMMARY[name]
    impl = getattr(_prtbake, name)
    keys = _prtbake.keywords()[name]
    params = []
    if first:
        params.append(_inspect.Parameter(first, _inspect.Parameter.POSITIONAL_OR_KEYWORD))
    if name == "ibl":
        params.append(_inspect.Parameter("out_dir", _inspect.Parameter.POSITIONAL_OR_KEYWORD))
    lines = [summary, "", "Keywords (name: values; meaning):"]
    for key, kind, default, values, meaning in keys:
        params.append(_inspect.Parameter(key, _inspect.Parameter.KEYWORD_ONLY, default=default))
        lines.append("  %s: %s; %s" % (key, values or ("true or false" if kind == "boolean" else "a path"), meaning))
    params.append(_inspect.Parameter("device", _inspect.Parameter.KEYWORD_ONLY, default=None))
    lines.append("  device: OpenCL device, \"cpu\", \"gpu\" or an index (default $PRTBAKE_DEVICE or auto)")
    params.append(_inspect.Parameter("progress", _inspect.Parameter.KEYWORD_ONLY, default=None))
    lines.append("  progress: a function progress(stage, fraction) called between pieces of the work (raising stops")
    lines.append("            the call, as Ctrl-C does: the call checks for it at the same points, within a second)")

    def call(*args: Any, **kwargs: Any) -> Any:
        return impl(*args, **kwargs)

    call.__name__ = call.__qualname__ = name
    call.__doc__ = "\n".join(lines)
    call.__signature__ = _inspect.Signature(params)  # type: ignore[attr-defined]
    return call


env = _product("env")
transport = _product("transport")
glossy = _product("glossy")
lut = _product("lut")
prefilter = _product("prefilter")
ibl = _product("ibl")
probes = _product("probes")
lightmap = _product("lightmap")
