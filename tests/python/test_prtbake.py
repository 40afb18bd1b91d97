"""The Python module against the command line of the same build: the same input gives the same
arrays, to the byte; a mesh and an environment given as arrays give what their files give; the
library's errors arrive as the matching Python exceptions with the library's message; no
references or memory leak over 1,000 calls; two threads bake what one does alone.

Every comparison is exact (np.array_equal on float32/float64, or bytes): the module calls the
same library functions with the same options as the command, on the same device (cpu)."""
import json
import os
import pathlib
import resource
import struct
import subprocess
import sys
import threading
import tracemalloc

import numpy as np
import pytest

from conftest import ASSETS, BUILD, CLI, ROOT, cli, data

os.environ.setdefault("PRTBAKE_DEVICE", "cpu")
sys.path.insert(0, str(BUILD / "python"))
import prtbake  # noqa: E402

SKY = ASSETS / "sky.exr"
SCENE = ASSETS / "scene.gltf"


def coefficients(path):
    return np.array(json.loads(pathlib.Path(path).read_text())["coefficients"], dtype=np.float64)


def make_grid_mesh(n=12):
    """A bumpy height field: (n+1)² vertices, 2n² triangles, vertices in the order a file's faces first use them."""
    x, z = np.meshgrid(np.linspace(-1, 1, n + 1), np.linspace(-1, 1, n + 1))
    y = 0.3 * np.sin(3 * x) * np.cos(2 * z)
    pos = np.stack([x, y, z], axis=-1).reshape(-1, 3).astype(np.float32)
    tris = []
    for r in range(n):
        for c in range(n):
            a, b, d, e = r * (n + 1) + c, r * (n + 1) + c + 1, (r + 1) * (n + 1) + c, (r + 1) * (n + 1) + c + 1
            tris += [(a, d, b), (b, d, e)]
    idx = np.array(tris, dtype=np.uint32)
    # Renumbered in the order the faces first use the vertices, as an OBJ loader numbers them.
    _, first = np.unique(idx.ravel(), return_index=True)
    order = idx.ravel()[np.sort(first)]
    renumber = np.empty(len(pos), np.uint32)
    renumber[order] = np.arange(len(order), dtype=np.uint32)
    return pos[order], renumber[idx]


def write_obj(path, pos, idx):
    with open(path, "w") as f:
        for p in pos:
            f.write("v %.9g %.9g %.9g\n" % tuple(float(v) for v in p))
        for t in idx:
            f.write("f %d %d %d\n" % tuple(int(v) + 1 for v in t))


# --- each product against the command ---

def test_env_file_matches_the_command(tmp_path):
    for args, kw in [([], {}), (["--order", "5", "--window", "hann", "--quantity", "irradiance"],
                                 dict(order=5, window="hann", quantity="irradiance")),
                     (["--yaw", "30"], dict(yaw=30.0)), (["--order", "auto"], dict(order="auto"))]:
        out = tmp_path / "e.json"
        cli("env", SKY, "-o", out, *args)
        r = prtbake.env(SKY, **kw)
        assert r.coeffs.dtype == np.float64 and r.coeffs.shape == (r.order ** 2, 3)
        assert np.array_equal(r.coeffs, coefficients(out)), args
        assert r.order == json.loads(out.read_text())["order"]


def write_hdr(path, codes):
    """A flat (uncompressed) Radiance file of RGBE codes (H, W, 4) uint8; returns the radiance stb_image decodes."""
    h, w, _ = codes.shape
    with open(path, "wb") as f:
        f.write(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (h, w))
        f.write(codes.tobytes())
    scale = np.ldexp(1.0, codes[..., 3].astype(np.int32) - 136).astype(np.float32)
    return codes[..., :3].astype(np.float32) * scale[..., None]


def test_env_array_matches_its_file(tmp_path):
    rng = np.random.default_rng(7)
    codes = rng.integers(16, 256, size=(32, 64, 4), dtype=np.uint8)
    codes[..., 3] = rng.integers(126, 132, size=(32, 64), dtype=np.uint8)
    radiance = write_hdr(tmp_path / "sky.hdr", codes)
    from_file = prtbake.env(tmp_path / "sky.hdr", order=4)
    from_array = prtbake.env(radiance, order=4)
    assert np.array_equal(from_file.coeffs, from_array.coeffs)
    assert from_array.layout == "latlong" and from_array.width == 64
    # float64 input is converted once and gives the same coefficients
    assert np.array_equal(prtbake.env(radiance.astype(np.float64), order=4).coeffs, from_file.coeffs)
    # A cube of six faces of radiance 1: L_00 = ∫ Y_00 dω = 2√π, the rest 0 (within 1e-5: the
    # float32 sums of the kernel, as the env product's own bound).
    r = prtbake.env(np.ones((6, 8, 8, 3), np.float32), order=2)
    assert r.layout == "faces" and r.coeffs.shape == (4, 3)
    assert np.allclose(r.coeffs[0], 2 * np.sqrt(np.pi), rtol=1e-5) and np.abs(r.coeffs[1:]).max() < 1e-5


def test_rotate_matches_the_command(tmp_path):
    cli("env", SKY, "-o", tmp_path / "e.json", "--order", "4")
    for args, kw in [(["--euler-zyz", "10,20,30"], dict(euler_zyz=(10, 20, 30))),
                     (["--quat", "0.9,0.1,0.3,0.2", "--method", "projection"],
                      dict(quat=(0.9, 0.1, 0.3, 0.2), method="projection"))]:
        cli("rotate", tmp_path / "e.json", "-o", tmp_path / "r.json", *args)
        got = prtbake.rotate(coefficients(tmp_path / "e.json"), **kw)
        assert np.array_equal(got, coefficients(tmp_path / "r.json"))


@pytest.mark.parametrize("mode", ["unshadowed", "shadowed", "interreflected"])
def test_transport_matches_the_command(tmp_path, mode):
    cli("transport", SCENE, "-o", tmp_path / "t.npy", "--mode", mode, "--samples", "128")
    r = prtbake.transport(SCENE, mode=mode, samples=128)
    expected = np.load(tmp_path / "t.npy")
    assert r.coeffs.dtype == expected.dtype and r.coeffs.shape == expected.shape
    assert r.coeffs.tobytes() == expected.tobytes()
    assert r.coeffs.base is not None  # owns the library's vector, not a copy


def test_mesh_from_arrays_matches_its_file(tmp_path):
    pos, idx = make_grid_mesh()
    write_obj(tmp_path / "grid.obj", pos, idx)
    loaded = prtbake.Mesh.load(tmp_path / "grid.obj")
    assert np.array_equal(loaded.positions, pos) and np.array_equal(loaded.indices, idx)
    from_arrays = prtbake.Mesh(pos, idx)
    assert np.array_equal(from_arrays.normals, loaded.normals)  # both filled the same way
    a = prtbake.transport(tmp_path / "grid.obj", samples=256)
    b = prtbake.transport(from_arrays, samples=256)
    c = prtbake.transport(prtbake.Mesh(pos.astype(np.float64), idx.astype(np.int64)), samples=256)
    assert a.coeffs.tobytes() == b.coeffs.tobytes() == c.coeffs.tobytes()
    # a mesh's arrays are views of the mesh (no copy), kept alive by the array
    p = prtbake.Mesh(pos, idx).positions
    assert p.base is not None and np.array_equal(p, pos)


def test_glossy_with_cpca_matches_the_command(tmp_path):
    out = tmp_path / "g.npy"
    cli("transport", SCENE, "--transfer", "matrix", "-o", out, "--samples", "64", "--cpca", "4,2",
        "--brdf", "ggx:0.4")
    r = prtbake.glossy(SCENE, samples=64, cpca_clusters=4, cpca_vectors=2, brdf="ggx", roughness=0.4)
    assert r.matrices.tobytes() == np.load(out).tobytes()
    npz = np.load(tmp_path / "g.cpca.npz")
    assert set(["means", "basis"]) <= set(npz.files)
    assert r.cpca["means"].tobytes() == npz["means"].tobytes()
    h = prtbake.glossy(SCENE, samples=64, dtype="float16")
    cli("transport", SCENE, "--transfer", "matrix", "-o", out, "--samples", "64", "--dtype", "float16")
    assert h.matrices.dtype == np.float16 and h.matrices.tobytes() == np.load(out).tobytes()


def test_lut_matches_the_command(tmp_path):
    cli("lut", "-o", tmp_path / "l.exr", "--size", "32", "--samples", "256", "--multiscatter")
    r = prtbake.lut(size=32, samples=256, multiscatter=True)
    exr = prtbake.read_exr(tmp_path / "l.exr")
    assert np.array_equal(exr["R"], r.a) and np.array_equal(exr["G"], r.b) and np.array_equal(exr["B"], r.third)


def ktx2_levels(path):
    """The level images of a KTX2 file as float32 RGBA arrays (RGBA32F files only), level 0 first."""
    b = pathlib.Path(path).read_bytes()
    count = struct.unpack_from("<I", b, 40)[0]
    levels = []
    for i in range(max(count, 1)):
        offset, length, _ = struct.unpack_from("<QQQ", b, 80 + 24 * i)
        levels.append(np.frombuffer(b[offset:offset + length], dtype=np.float32))
    return levels


def test_prefilter_matches_the_command(tmp_path):
    cli("prefilter", SKY, "-o", tmp_path / "p.ktx2", "--size", "32", "--float32")
    r = prtbake.prefilter(SKY, size=32)
    files = ktx2_levels(tmp_path / "p.ktx2")
    assert len(files) == len(r.levels)
    for level, stored in zip(r.levels, files):
        rgba = stored.reshape(level.shape[:3] + (4,))
        assert np.array_equal(rgba[..., :3], level)


def test_ibl_matches_the_command(tmp_path):
    cli("ibl", SKY, "-o", tmp_path / "cmd", "--size", "16", "--lut-size", "16")
    r = prtbake.ibl(SKY, tmp_path / "py", size=16, lut_size=16)
    files = lambda d: sorted(str(p.relative_to(d)) for p in d.rglob("*") if p.is_file())
    names = files(tmp_path / "cmd")
    assert names == files(tmp_path / "py") and len(names) > 10
    for name in names:
        if not name.endswith(".json"):  # the JSON files record timings
            assert (tmp_path / "cmd" / name).read_bytes() == (tmp_path / "py" / name).read_bytes(), name
    assert len(r.files) > 0


def test_run_matches_the_command(tmp_path):
    job = {"jobs": [{"id": "lut", "type": "lut", "size": 16, "samples": 64,
                     "outputs": {"exr": "a/lut.exr"}}]}
    (tmp_path / "jobs.json").write_text(json.dumps(job))
    r = prtbake.run(tmp_path / "jobs.json")
    assert (r.ok, r.failed) == (1, 0)
    first = (tmp_path / "a" / "lut.exr").read_bytes()
    assert prtbake.run(tmp_path / "jobs.json").skipped == 1  # up to date
    cli("run", tmp_path / "jobs.json", "--force")
    assert (tmp_path / "a" / "lut.exr").read_bytes() == first


def test_run_confined_to_roots(tmp_path):
    """input_root / output_root as the command's --input-root / --output-root (docs/jobs.md)."""
    (tmp_path / "out").mkdir()
    (tmp_path / "secret").mkdir()
    job = {"jobs": [{"id": "in", "type": "lut", "size": 8, "samples": 16, "outputs": {"exr": "out/a.exr"}},
                    {"id": "escape", "type": "lut", "size": 8, "samples": 16, "outputs": {"exr": "secret/a.exr"}}]}
    (tmp_path / "jobs.json").write_text(json.dumps(job))
    r = prtbake.run(tmp_path / "jobs.json", output_root=tmp_path / "out")
    assert (r.ok, r.failed) == (1, 1)
    assert (tmp_path / "out" / "a.exr").exists()
    assert list((tmp_path / "secret").iterdir()) == []
    with pytest.raises(ValueError, match="--output-root"):
        prtbake.run(tmp_path / "jobs.json", output_root=tmp_path / "missing")


# --- keywords: the declaration's, with the command line's checks ---

def test_keywords_are_the_commands_options():
    for product, keys in prtbake.keywords().items():
        names = {k[0] for k in keys}
        help_text = cli("keys").stdout
        for name in names:
            assert "`%s`" % name in help_text
    # a value each refuses alike: the library's words
    for kw, args in [(dict(order=0), ["--order", "0"]), (dict(samples=0), ["--samples", "0"]),
                     (dict(mode="glossy"), ["--mode", "glossy"]), (dict(tolerance=0.01, samples=8),
                                                                   ["--tolerance", "0.01", "--samples", "8"])]:
        with pytest.raises(ValueError) as e:
            prtbake.transport(SCENE, **kw)
        p = cli("transport", SCENE, "-o", "/nonexistent/t.npy", *args, check=False)
        assert p.returncode != 0
        assert str(e.value) in p.stderr, (str(e.value), p.stderr)


def test_errors_are_python_exceptions(tmp_path):
    with pytest.raises(ValueError, match="not a keyword of transport"):
        prtbake.transport(SCENE, sample=3)
    with pytest.raises(prtbake.InputError, match="missing.obj"):
        prtbake.transport(tmp_path / "missing.obj")
    (tmp_path / "bad.exr").write_bytes(b"not an exr")
    with pytest.raises(prtbake.InputError, match="bad.exr"):
        prtbake.env(tmp_path / "bad.exr")
    with pytest.raises(prtbake.InputError, match="out of range"):
        prtbake.Mesh(np.zeros((3, 3), np.float32), np.array([[0, 1, 3]]))
    with pytest.raises(prtbake.InputError):
        prtbake.Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]], np.float32), np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="lat-long"):
        prtbake.env(np.zeros((4, 4, 3), np.float32))
    with pytest.raises(ValueError, match="no device with that index"):
        prtbake.lut(size=8, samples=8, device="99")
    if not any(d["type"] == "gpu" for d in prtbake.devices()):
        with pytest.raises(prtbake.DeviceError):
            prtbake.lut(size=8, samples=8, device="gpu")
    assert issubclass(prtbake.InputError, prtbake.Error)


def test_an_output_that_would_destroy_an_input_is_refused(tmp_path):
    """As the command refuses it: a preview's out= that names its input (by any path or link), and
    an ibl package directory that holds the environment (a package replaces its directory whole:
    the environment was deleted once the new package was in place). Nothing is read or written."""
    import shutil
    sky = tmp_path / "sky.exr"
    shutil.copyfile(SKY, sky)
    (tmp_path / "link.exr").symlink_to("sky.exr")
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "ibl.json").write_text("{}")  # a previous package: replaced whole
    shutil.copyfile(SKY, pkg / "sky.exr")
    before = sky.read_bytes()
    for call, out in [(lambda: prtbake.preview_env(sky, size=16, out=sky), "sky.exr"),
                      (lambda: prtbake.preview_env(sky, size=16, out=tmp_path / "link.exr"), "link.exr"),
                      (lambda: prtbake.preview_prefilter(str(tmp_path / "." / "sky.exr"), out=sky), "sky.exr"),
                      (lambda: prtbake.ibl(pkg / "sky.exr", pkg, size=16), "pkg")]:
        with pytest.raises(ValueError, match="would (overwrite|delete) the input") as e:
            call()
        assert str(e.value).split(": ")[0].endswith(out)  # the output is the subject
    assert sky.read_bytes() == before and (pkg / "sky.exr").read_bytes() == before
    assert sorted(p.name for p in pkg.iterdir()) == ["ibl.json", "sky.exr"]


# --- leaks and threads ---

def rss_kib():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() // 1024


def test_no_leaks_over_a_thousand_calls():
    pos, idx = make_grid_mesh(4)
    mesh = prtbake.Mesh(pos, idx)
    sky = np.ones((8, 16, 3), np.float32)

    def calls(n):
        for _ in range(n):
            prtbake.env(sky, order=3)
            prtbake.transport(mesh, samples=16, mode="unshadowed")
            prtbake.Mesh(pos, idx).positions

    calls(100)  # warm: programs built, allocator pools grown
    refs = sys.getrefcount(mesh), sys.getrefcount(sky), sys.getrefcount(pos)
    tracemalloc.start()
    before_py, before_rss = tracemalloc.take_snapshot(), rss_kib()
    calls(1000)
    after_py, after_rss = tracemalloc.take_snapshot(), rss_kib()
    tracemalloc.stop()
    grown = sum(s.size_diff for s in after_py.compare_to(before_py, "filename") if s.size_diff > 0)
    assert (sys.getrefcount(mesh), sys.getrefcount(sky), sys.getrefcount(pos)) == refs
    # Bounds: Python objects kept over 1,000 calls under 64 KiB (a leaked result would keep
    # ~1,000 objects of 100+ bytes), the process under 4 MiB more (each call's arrays are
    # ~1 KiB: a leak of one per call is 3 MiB, of the transport's buffers far more).
    assert grown < 64 * 1024, grown
    assert after_rss - before_rss < 4096, (before_rss, after_rss)


def test_two_threads_give_what_one_gives():
    pos, idx = make_grid_mesh(16)
    mesh = prtbake.Mesh(pos, idx)
    alone = [prtbake.transport(mesh, samples=256, seed=s).coeffs for s in (1, 2)]
    alone.append(prtbake.lut(size=16, samples=128).a)
    got = [None, None, None]

    def bake(i):
        got[i] = prtbake.transport(mesh, samples=256, seed=i + 1).coeffs if i < 2 else prtbake.lut(size=16,
                                                                                                 samples=128).a
    threads = [threading.Thread(target=bake, args=(i,)) for i in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for a, b in zip(alone, got):
        assert a.tobytes() == b.tobytes()


# --- the stubs and the examples ---

def test_stubs_type_check_an_example(tmp_path):
    example = tmp_path / "example.py"
    example.write_text(
        "import numpy as np\nfrom numpy.typing import NDArray\nimport prtbake\n"
        "sky = prtbake.env('sky.exr', order=3, window='hann')\n"
        "c: NDArray[np.float64] = sky.coeffs\n"
        "t = prtbake.transport(prtbake.Mesh(np.zeros((3, 3)), np.array([[0, 1, 2]])), samples=64)\n"
        "n: int = t.order\n")
    bad = tmp_path / "bad.py"
    bad.write_text("import prtbake\nprtbake.transport('m.obj', samples='many')\nprtbake.env('s.exr', window='box')\n")
    env = dict(os.environ, MYPYPATH=str(BUILD / "python"))
    run = lambda f: subprocess.run([sys.executable, "-m", "mypy", "--strict", "--no-incremental",
                                    "--cache-dir", str(tmp_path / "cache"), str(f)],
                                   capture_output=True, text=True, env=env, timeout=300)
    try:
        import mypy  # noqa: F401
    except ImportError:
        if os.environ.get("PRTBAKE_FORBID_SKIPS"):
            pytest.fail("mypy is not installed (PRTBAKE_FORBID_SKIPS is set)")
        pytest.skip("mypy is not installed")
    good = run(example)
    assert good.returncode == 0, good.stdout
    wrong = run(bad)
    assert wrong.returncode != 0 and "samples" in wrong.stdout and "window" in wrong.stdout, wrong.stdout


def test_examples_run_and_type_check(tmp_path):
    examples = ROOT / "examples" / "python"
    env = dict(os.environ, PYTHONPATH=str(BUILD / "python"))
    p = subprocess.run([sys.executable, str(examples / "blender_mesh.py")], capture_output=True, text=True,
                       env=env, timeout=300)
    assert p.returncode == 0 and "shaded 12 vertices" in p.stdout, p.stderr
    p = subprocess.run([sys.executable, str(examples / "bake_folder.py"), str(ASSETS), str(SKY), str(tmp_path),
                        "--samples", "64"], capture_output=True, text=True, env=env, timeout=300)
    assert p.returncode == 0, p.stderr
    baked = np.load(tmp_path / "scene.transport.npy")
    assert baked.tobytes() == prtbake.transport(SCENE, samples=64).coeffs.tobytes()
    assert (tmp_path / "ibl" / "ibl.json").exists()
    try:
        import mypy  # noqa: F401
    except ImportError:
        pytest.skip("mypy is not installed")
    p = subprocess.run([sys.executable, "-m", "mypy", "--strict", "--no-incremental", "--cache-dir",
                        str(tmp_path / "cache"), *map(str, sorted(examples.glob("*.py")))],
                       capture_output=True, text=True, env=dict(env, MYPYPATH=str(BUILD / "python")), timeout=300)
    assert p.returncode == 0, p.stdout


# --- progress and Ctrl-C ---

def test_progress_reports_and_changes_nothing():
    pos, idx = make_grid_mesh(40)
    mesh = prtbake.Mesh(pos, idx)
    seen = []
    with_hook = prtbake.transport(mesh, samples=2048, mode="interreflected", bounces=2,
                                  progress=lambda stage, f: seen.append((stage, f)))
    plain = prtbake.transport(mesh, samples=2048, mode="interreflected", bounces=2)
    assert with_hook.coeffs.tobytes() == plain.coeffs.tobytes()  # blocks of vertices: the same bits
    stages = [s for s, _ in seen]
    assert "transport: direct" in stages and "transport: bounce" in stages
    direct = [f for s, f in seen if s == "transport: direct"]
    assert direct == sorted(direct) and direct[-1] == 1.0
    lut = []
    prtbake.lut(size=32, samples=64, progress=lambda s, f: lut.append(f))
    assert lut and lut[-1] == 1.0


def test_a_raising_progress_function_stops_the_call():
    pos, idx = make_grid_mesh(40)

    class Stop(Exception):
        pass

    def stop(stage, fraction):
        raise Stop(stage)

    with pytest.raises(Stop, match="transport: direct"):
        prtbake.transport(prtbake.Mesh(pos, idx), samples=1024, progress=stop)
    with pytest.raises(ValueError, match="progress"):
        prtbake.lut(size=8, progress=3)


def test_ctrl_c_stops_a_long_call_within_a_second():
    import signal
    import time
    pos, idx = make_grid_mesh(300)  # 90,601 vertices: several seconds at 4096 samples here
    mesh = prtbake.Mesh(pos, idx)
    sent = []

    def interrupt():
        time.sleep(0.5)
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)

    threading.Thread(target=interrupt).start()
    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        prtbake.transport(mesh, samples=4096)
    stopped = time.perf_counter()
    assert sent, "the call ended before the signal: make the work longer"
    # Bound: a block of work is about 4 M rays (0.25 s on this 2-core machine); 1 s is the goal.
    assert stopped - sent[0] < 1.0, (stopped - sent[0], stopped - t0)


# --- previews ---

def png_pixels(path):
    """The pixels of an 8-bit RGB or RGBA PNG (zlib and the five row filters), as (H, W, C) uint8."""
    import zlib
    b = pathlib.Path(path).read_bytes()
    pos, idat, w = 8, b"", 0
    while pos < len(b):
        n, kind = struct.unpack(">I4s", b[pos:pos + 8])
        body = b[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, colour = struct.unpack(">IIBB", body[:10])
            assert depth == 8 and colour in (2, 6)
            c = 3 if colour == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + w * c)
    out = np.zeros((h, w * c), np.int32)
    for y in range(h):
        f, row = raw[y, 0], raw[y, 1:].astype(np.int32)
        up = out[y - 1] if y else np.zeros(w * c, np.int32)
        for x in range(w * c):
            left = out[y, x - c] if x >= c else 0
            ul = up[x - c] if x >= c and y else 0
            if f == 0: p = 0
            elif f == 1: p = left
            elif f == 2: p = up[x]
            elif f == 3: p = (left + up[x]) // 2
            else:
                pa, pb, pc = abs(up[x] - ul), abs(left - ul), abs(left + up[x] - 2 * ul)
                p = left if pa <= pb and pa <= pc else up[x] if pb <= pc else ul
            out[y, x] = (row[x] + p) & 255
    return out.reshape(h, w, c).astype(np.uint8)


def test_previews_match_the_command(tmp_path):
    cli("env", SKY, "-o", tmp_path / "sky.json")
    cli("transport", SCENE, "-o", tmp_path / "t.npy", "--samples", "64")
    cli("preview", "mesh", SCENE, "--transport", tmp_path / "t.npy", "--env", tmp_path / "sky.json",
        "-o", tmp_path / "cmd_mesh.png", "--size", "96x64", "--view", "side")
    img = prtbake.preview_mesh(SCENE, prtbake.transport(SCENE, samples=64), prtbake.env(SKY), size=(96, 64),
                               view="side", out=tmp_path / "py_mesh.png")
    assert img.shape == (64, 96, 3) and img.dtype == np.float32 and img.max() > 0
    assert np.array_equal(png_pixels(tmp_path / "cmd_mesh.png"), png_pixels(tmp_path / "py_mesh.png"))
    cli("preview", "env", SKY, "-o", tmp_path / "cmd_env.png", "--size", "64", "--order", "5")
    prtbake.preview_env(SKY, order=5, size=64, out=tmp_path / "py_env.png")
    assert np.array_equal(png_pixels(tmp_path / "cmd_env.png"), png_pixels(tmp_path / "py_env.png"))
    cli("preview", "prefilter", SKY, "-o", tmp_path / "cmd_pre.png", "--size", "32", "--base", "16")
    prtbake.preview_prefilter(SKY, size=16, panel_width=32, out=tmp_path / "py_pre.png")
    assert np.array_equal(png_pixels(tmp_path / "cmd_pre.png"), png_pixels(tmp_path / "py_pre.png"))
    cli("lut", "-o", tmp_path / "l.exr", "--size", "16", "--samples", "64")
    cli("preview", "lut", tmp_path / "l.exr", "-o", tmp_path / "cmd_lut.png", "--size", "64")
    prtbake.preview_lut(prtbake.lut(size=16, samples=64), size=64, out=tmp_path / "py_lut.png")
    assert np.array_equal(png_pixels(tmp_path / "cmd_lut.png"), png_pixels(tmp_path / "py_lut.png"))


def test_an_environment_array_is_read_in_place(tmp_path):
    # A 100 MB float32 lat-long: the call's peak rise stays well under the array's size when
    # the texels are read where they are (a copy would add 100 MB); float64 is converted once.
    code = ("import resource, numpy as np, prtbake\n"
            "sky = np.ones((2048, 4096, 3), np.{dtype}); sky[:1024] *= 2\n"
            "prtbake.env(np.ones((8, 16, 3), np.float32))\n"
            "before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
            "r = prtbake.env(sky, order=3)\n"
            "after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
            "print((after - before) // 1024)\n")
    env = dict(os.environ, PYTHONPATH=str(BUILD / "python"))
    rise = {}
    for dtype in ("float32", "float64"):
        p = subprocess.run([sys.executable, "-c", code.format(dtype=dtype)], capture_output=True, text=True,
                           env=env, timeout=300)
        assert p.returncode == 0, p.stderr
        rise[dtype] = int(p.stdout.split()[-1])
    # Bounds: the float32 array (96 MiB) costs under 32 MiB more (the kernel's row sums and the
    # device's small buffers); the float64 one gets its one float32 copy (96 MiB) and no more
    # (its own creation's temporaries may already have raised the peak: no lower bound).
    assert rise["float32"] < 32, rise
    assert rise["float64"] < 160, rise
    # Invalid texels: refused, or clamped in a copy (the caller's array is left as it was).
    sky = np.ones((8, 16, 3), np.float32)
    sky[2, 3, 1] = np.nan
    with pytest.raises(prtbake.InputError, match="array"):
        prtbake.env(sky)
    r = prtbake.env(sky, clamp_invalid=True)
    assert r.clamped_texels == 1 and np.isnan(sky[2, 3, 1])


def test_probes_match_the_command(tmp_path):
    args = ["--resolution", "4,2,3", "--samples", "64", "--transport-samples", "64"]
    cli("probes", SCENE, "-o", tmp_path / "grid", *args)
    expected = np.load(tmp_path / "grid" / "probes.npy")
    r = prtbake.probes(SCENE, resolution=[4, 2, 3], samples=64, transport_samples=64)
    assert r.coeffs.shape == expected.shape == (3, 2, 4, 9, 3)
    assert r.coeffs.tobytes() == expected.tobytes()
    assert r.coeffs.base is not None  # the library's vector, not a copy
    assert r.state.shape == (3, 2, 4) and r.positions.shape == (3, 2, 4, 3)
    # the environment as coefficients gives what its JSON gives
    sky = prtbake.env(SKY, order=3)
    sh_json = tmp_path / "sky.json"
    cli("env", SKY, "-o", sh_json, "--order", "3")
    a = prtbake.probes(SCENE, resolution=[2, 2, 2], samples=32, bounces=0, env=sky.coeffs)
    b = prtbake.probes(SCENE, resolution=[2, 2, 2], samples=32, bounces=0, env=sh_json)
    assert np.allclose(a.coeffs, b.coeffs, rtol=1e-6, atol=1e-6)  # the JSON's decimal digits
    with pytest.raises(ValueError, match="bounds"):
        prtbake.probes(SCENE, bounds=[0, 0, 0, 1, -1, 1])


LIGHTMAP_OBJ = """v -1 0 -1
v 1 0 -1
v 1 0 1
v -1 0 1
v -0.3 0.3 -0.3
v 0.3 0.3 -0.3
v 0.3 0.3 0.3
v -0.3 0.3 0.3
vt 0 0.5
vt 1 0.5
vt 1 1
vt 0 1
vt 0.1 0.1
vt 0.4 0.1
vt 0.4 0.4
vt 0.1 0.4
vn 0 1 0
vn 0 -1 0
f 1/1/1 4/4/1 3/3/1
f 1/1/1 3/3/1 2/2/1
f 5/5/2 6/6/2 7/7/2
f 5/5/2 7/7/2 8/8/2
"""


def write_corner_gltf(path, material, texture_png=None):
    """A floor (y = 0) and a wall (x = 0) meeting at a corner, lighting each other: one primitive, UV set 0
    for a base colour texture, UV set 1 for a lightmap (the two quads' charts apart)."""
    import base64
    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1], [0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]], np.float32)
    nrm = np.array([[0, 1, 0]] * 4 + [[1, 0, 0]] * 4, np.float32)
    uv0 = np.array([[0, 0], [1, 0], [1, 1], [0, 1]] * 2, np.float32)
    uv1 = np.array([[.05, .05], [.45, .05], [.45, .95], [.05, .95], [.55, .05], [.95, .05], [.95, .95], [.55, .95]], np.float32)
    idx = np.array([0, 3, 2, 0, 2, 1, 4, 5, 6, 4, 6, 7], np.uint16)
    blobs = [pos, nrm, uv0, uv1, idx]
    buf, views, off = b"", [], 0
    for a in blobs:
        views.append({"buffer": 0, "byteOffset": off, "byteLength": a.nbytes})
        buf += a.tobytes()
        off += a.nbytes
    acc = [{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1]},
           {"bufferView": 1, "componentType": 5126, "count": 8, "type": "VEC3"},
           {"bufferView": 2, "componentType": 5126, "count": 8, "type": "VEC2"},
           {"bufferView": 3, "componentType": 5126, "count": 8, "type": "VEC2"},
           {"bufferView": 4, "componentType": 5123, "count": 12, "type": "SCALAR"}]
    g = {"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
         "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2, "TEXCOORD_1": 3},
                                     "indices": 4, "material": 0}]}],
         "materials": [material], "accessors": acc, "bufferViews": views,
         "buffers": [{"byteLength": len(buf), "uri": "data:application/octet-stream;base64," + base64.b64encode(buf).decode()}]}
    if texture_png is not None:
        g["textures"] = [{"source": 0}]
        g["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(texture_png).decode()}]
    pathlib.Path(path).write_text(json.dumps(g))
    return path


def uniform_png(rgb, size=8):
    """An 8-bit RGB PNG of one colour (sRGB codes)."""
    import zlib
    row = b"\0" + bytes(rgb) * size
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", size, size, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(row * size)) + chunk(b"IEND", b""))


def test_the_bakes_that_use_the_albedo_read_the_base_colour_texture(tmp_path):
    # A corner textured in one colour bakes as the same corner whose base colour factor is that
    # colour, linear: the same rays, the same float albedo (equal to float rounding in the bounce
    # sums, 1e-5); as white (the factor alone, the control) it differs.
    code = (180, 120, 60)
    linear = [c / 255 / 12.92 if c / 255 <= 0.04045 else ((c / 255 + 0.055) / 1.055) ** 2.4 for c in code]
    textured = write_corner_gltf(tmp_path / "textured.gltf", {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
                                 uniform_png(code))
    plain = write_corner_gltf(tmp_path / "plain.gltf", {"pbrMetallicRoughness": {"baseColorFactor": linear + [1]}})
    assert np.allclose(prtbake.Mesh.load(textured).albedo, np.array([linear] * 8), rtol=0, atol=1e-7)
    bakes = {
        "transport": lambda m, **k: prtbake.transport(m, mode="interreflected", bounces=2, order=2, samples=64, **k).coeffs,
        "probes": lambda m, **k: prtbake.probes(m, resolution=[2, 2, 2], samples=64, transport_samples=64, bounces=2,
                                                bounds=[0.2, 0.2, 0.2, 0.8, 0.8, 0.8], **k).coeffs,
        "lightmap": lambda m, **k: prtbake.lightmap(m, uv=1, size=16, samples=64, products="irradiance", bounces=1,
                                                    **k).irradiance,
    }
    for name, bake in bakes.items():
        t, p, white = bake(textured), bake(plain), bake(textured, albedo=1.0)
        assert t.shape == p.shape, name  # coloured, as the factor's
        assert np.abs(t - p).max() <= 1e-5, name
        if white.shape != t.shape:  # grey transport (V, n²) beside coloured (V, 3, n²)
            white = white[:, None, :]
        assert np.abs(t - white).max() > 1e-3, name


def test_lightmap_matches_the_command(tmp_path):
    # A floor with a square roof above its middle; the roof's chart apart from the floor's.
    obj = tmp_path / "floor.obj"
    obj.write_text(LIGHTMAP_OBJ)
    cli("lightmap", obj, "-o", tmp_path / "lm", "--size", "32", "--samples", "64", "--products", "ao,bent,sh",
        "--sh-order", "2")
    exr = prtbake.read_exr(tmp_path / "lm" / "ao.exr")
    r = prtbake.lightmap(obj, size=32, samples=64, products="ao,bent,sh", sh_order=2)
    assert r.ao.shape == (32, 32) and r.bent.shape == (32, 32, 3) and r.irradiance is None
    assert np.array_equal(exr["Y"], r.ao)
    sh = prtbake.read_exr(tmp_path / "lm" / "sh.exr")
    assert r.sh.shape == (32, 32, 4, 3) and r.sh_order == 2
    assert np.array_equal(sh["SH3.G"], r.sh[:, :, 3, 1])
    assert r.ao.base is not None  # the library's vector, not a copy
    assert r.ao.min() < 0.9 and r.uv_set == 0  # the roof shades the floor
    # The preview: of the command's directory and of the library's result, as the command draws it.
    cli("preview", "lightmap", obj, "--lightmap", tmp_path / "lm", "-o", tmp_path / "cmd_lm.png", "--size", "96x64",
        "--view", "top")
    img = prtbake.preview_lightmap(obj, tmp_path / "lm", size=(96, 64), view="top", out=tmp_path / "py_lm.png")
    assert img.shape == (3 * 64, 96 + 64, 3) and img.dtype == np.float32
    assert np.array_equal(png_pixels(tmp_path / "cmd_lm.png"), png_pixels(tmp_path / "py_lm.png"))
    assert np.array_equal(prtbake.preview_lightmap(obj, r, size=(96, 64), view="top"), img)
    with pytest.raises(ValueError, match="LightmapResult"):
        prtbake.preview_lightmap(obj, 3)
    # The same mesh from arrays (OBJ's v flipped to glTF's convention) bakes the same texels.
    m = prtbake.Mesh.load(obj)
    assert m.uv_sets == [0]
    rows = [l.split()[1:] for l in LIGHTMAP_OBJ.splitlines()]
    v = np.array([x for l, x in zip(LIGHTMAP_OBJ.splitlines(), rows) if l.startswith("v ")], np.float32)
    vt = np.array([x for l, x in zip(LIGHTMAP_OBJ.splitlines(), rows) if l.startswith("vt ")], np.float32)
    uv = np.stack([vt[:, 0], 1 - vt[:, 1]], axis=1)
    normals = np.array([[0, 1, 0]] * 4 + [[0, -1, 0]] * 4, np.float32)
    tris = np.array([[0, 3, 2], [0, 2, 1], [4, 5, 6], [4, 6, 7]])
    a = prtbake.lightmap(prtbake.Mesh(v, tris, normals=normals, uvs=[uv]), size=32, samples=64, products="ao,bent")
    assert np.allclose(a.ao, r.ao, atol=1e-6) and np.array_equal(a.state, r.state)
    # With tangents (+x everywhere, w = +1): bent also in tangent space, its first component the
    # object-space x (t = x is orthogonal to both faces' normals), unit length; none without.
    assert a.bent_tangent is None
    tangents = np.tile(np.array([[1, 0, 0, 1]], np.float32), (8, 1))
    t = prtbake.lightmap(prtbake.Mesh(v, tris, normals=normals, uvs=[uv], tangents=tangents), size=32, samples=64,
                         products="bent")
    valid = (t.state == 1) | (t.state == 2)
    assert t.bent_tangent.shape == (32, 32, 3) and valid.sum() > 500
    assert np.allclose(t.bent_tangent[valid][:, 0], t.bent[valid][:, 0], atol=1e-5)
    assert np.allclose(np.linalg.norm(t.bent_tangent[valid], axis=1), 1, atol=1e-5)
    with pytest.raises(ValueError, match="tangents"):
        prtbake.Mesh(v, tris, tangents=tangents[:3])
    with pytest.raises(prtbake.InputError, match="no UV set 1"):
        prtbake.lightmap(obj, uv=1)
    with pytest.raises(ValueError, match="size"):
        prtbake.lightmap(obj, size=0)
