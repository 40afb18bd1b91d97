"""The Python module's cost beside the library's, in one run: writes bench/results/python.md.

1. Overhead: a binding call against the same library call from C++ (build/bench/bench_call),
   from the smallest inputs up: lut 16² at 64 samples to the command's default 128² at 1,024,
   env of a 64×32 to a 2048×1024 lat-long array, transport of assets/scene.gltf (4,906 vertices)
   at 64 samples. ROUNDS rounds (default 5), each timing CALLS calls (default 200; fewer for the
   slow cases) of every case in C++ then in Python, each call alone after 20 warm-up calls; the
   median per call of each round, then the median over rounds, the per-round ratio Python/C++,
   and the difference. Paired: each Python call's wall time against the library's own time
   reported within that call (its `seconds`): the binding's cost per call, free of the noise
   between processes.
2. Memory: the knot of bench_embree.sh (102,400 vertices) → transport at order 8, 64 samples →
   NumPy, in a fresh Python process (peak resident memory from getrusage, the mesh as arrays
   and from the file), beside `prtbake transport` of the same mesh and options (/usr/bin/time).
   The output is 102,400 × 64 float32 = 26.2 MB: a copy of it would add that much to the peak.

    PYTHONPATH=build/python /usr/bin/python3 bench/bench_python.py [BUILD]
"""
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
BUILD = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "build"
sys.path.insert(0, str(BUILD / "python"))
os.environ.setdefault("PRTBAKE_DEVICE", "cpu")
import numpy as np  # noqa: E402
import prtbake  # noqa: E402

ROUNDS = int(os.environ.get("ROUNDS", "5"))
CALLS = int(os.environ.get("CALLS", "200"))
SCENE = ROOT / "assets" / "scene.gltf"


# (label, bench_call's arguments after CALLS, calls per round / CALLS)
CASES = [("lut 16², 64 samples", ["lut", "16", "64"], 1), ("lut 32², 256 samples", ["lut", "32", "256"], 1),
         ("lut 128², 1,024 samples (the default)", ["lut", "128", "1024"], 0.1),
         ("env 64×32", ["env", "64"], 1), ("env 256×128", ["env", "256"], 1), ("env 2048×1024", ["env", "2048"], 0.25),
         ("transport, scene.gltf, 64 samples", ["transport", str(SCENE)], 0.25)]


def python_call(args, calls):
    what = args[0]
    if what == "lut":
        fn = lambda: prtbake.lut(size=int(args[1]), samples=int(args[2]))  # noqa: E731
    elif what == "env":
        sky = np.ones((int(args[1]) // 2, int(args[1]), 3), np.float32)
        fn = lambda: prtbake.env(sky, order=3)  # noqa: E731
    else:
        mesh = prtbake.Mesh.load(args[1])
        fn = lambda: prtbake.transport(mesh, samples=64)  # noqa: E731
    for _ in range(20):
        fn()
    t, own = [], []
    for _ in range(calls):
        r = None  # the previous result freed before the clock starts (a large array's munmap)
        t0 = time.perf_counter()
        r = fn()
        t.append(time.perf_counter() - t0)
        own.append(r.seconds)
    # The call's wall time, and paired with the time the library reports for itself within the
    # same call: the binding's own time and the call's ratio to the library's.
    return (statistics.median(t), statistics.median([a - b for a, b in zip(t, own)]),
            statistics.median([a / b for a, b in zip(t, own)]))


def cxx_call(args, calls):
    out = subprocess.run([str(BUILD / "bench" / "bench_call"), args[0], str(calls)] + args[1:], cwd=ROOT,
                         capture_output=True, text=True, check=True).stdout.split()
    return float(out[2])


def peak_mib(code):
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                       env=dict(os.environ, PYTHONPATH=str(BUILD / "python")))
    return p.stdout.strip()


def main():
    rows = []
    for label, args, share in CASES if os.environ.get("PART") != "memory" else ():
        c, p, own, paired = [], [], [], []
        calls = max(10, int(CALLS * share))
        for _ in range(ROUNDS):
            c.append(cxx_call(args, calls))
            wall, binding, ratio = python_call(args, calls)
            p.append(wall)
            own.append(binding)
            paired.append(ratio)
        ratios = [b / a for a, b in zip(c, p)]
        rows.append((label, statistics.median(c), statistics.median(p), statistics.median(ratios), min(ratios),
                     max(ratios), statistics.median([b - a for a, b in zip(c, p)]), statistics.median(own),
                     statistics.median(paired)))
    with tempfile.TemporaryDirectory() as work:
        knot = pathlib.Path(work) / "knot.obj"
        subprocess.run([str(BUILD / "bench" / "bench_embree"), "--write-knot", str(knot)], check=True)
        measure = ("import resource, prtbake, numpy as np\n"
                   "startup = [int(l.split()[1]) for l in open('/proc/self/status') if l.startswith('VmRSS')][0]\n"
                   "m = prtbake.Mesh.load(%r)\n"
                   "{make}\n"
                   "before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
                   "t = prtbake.transport(m, order=8, samples=64)\n"
                   "after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
                   "print('%%.1f %%.1f %%.1f %%.1f' %% (before / 1024, after / 1024, t.coeffs.nbytes / 2**20,"
                   " startup / 1024))\n") % str(knot)
        # Warm: the order-8 programs built and cached (PoCL's compiler would add ~135 MiB to the first run).
        subprocess.run([str(BUILD / "prtbake"), "transport", str(knot), "-o", str(pathlib.Path(work) / "k.npy"),
                        "--order", "8", "--samples", "64", "--quiet"], check=True)
        cxx = subprocess.run([str(BUILD / "bench" / "bench_call"), "peak", "1", str(knot)], capture_output=True,
                             text=True, check=True).stdout
        from_file = peak_mib(measure.format(make="pass"))
        from_arrays = peak_mib(measure.format(make="m = prtbake.Mesh(np.array(m.positions), np.array(m.indices), "
                                                   "np.array(m.normals)); import gc; gc.collect()"))
        cli = subprocess.run(["/usr/bin/time", "-f", "%M", str(BUILD / "prtbake"), "transport", str(knot), "-o",
                              str(pathlib.Path(work) / "k.npy"), "--order", "8", "--samples", "64", "--quiet"],
                             capture_output=True, text=True, check=True).stderr.strip().splitlines()[-1]
    cpu = [l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")][0]
    lines = ["# The Python module beside the library", "",
             "bench/bench_python.py, %s, %d cores (%s), CPU device; %d rounds of %d calls each." % (
                 time.strftime("%Y-%m-%d"), os.cpu_count(), cpu, ROUNDS, CALLS), "",
             "## A call, from the smallest inputs up", "",
             "Two measures. Between processes: the median call of bench_call (C++) and of the module, round by",
             "round. Paired, within each Python call: its wall time against the time the library reports for",
             "itself inside that same call (LutResult.seconds and TransportResult.seconds: computeLut and",
             "computeTransport whole; EnvResult.seconds: from wrapping the array, without a copy, to the",
             "projection's end), so that the machine's load and the processes' differences cancel: the",
             "difference is the binding's own time (keywords, device lookup, result objects).", "",
             "| call | C++ library [ms] | Python module [ms] | Python / C++, median of rounds (min–max) | Python − C++ [µs] "
             "| binding's own time, paired [µs] | Python / library, paired |",
             "|---|---|---|---|---|---|---|"]
    for label, c, p, r, lo, hi, d, own, paired in rows:
        lines.append("| %s | %.3f | %.3f | %.3f (%.3f–%.3f) | %.0f | %.1f | %.3f |" % (
            label, 1e3 * c, 1e3 * p, r, lo, hi, 1e6 * d, 1e6 * own, paired))
    b, a, out, s1 = from_file.split()
    b2, a2, _, s2 = from_arrays.split()
    b3, a3, _, s3 = cxx.split()
    lines += ["", "env: a lat-long array of ones, order 3; both check every value for NaN, Inf and negatives",
              "(validateEnvironment, as the module does for an array and loadEnvironment for a file), then project",
              "(the Python call converts nothing: float32, C order); transport: assets/scene.gltf (4,906",
              "vertices), shadowed, 64 samples (the Python call takes the loaded prtbake.Mesh).", "",
              "## Memory: mesh → transport → NumPy", "",
              "The knot (102,400 vertices, 204,800 triangles), order 8, 64 samples: the output is %s MiB." % out, "",
              "| path | resident at start-up [MiB] | peak before the call [MiB] | peak after [MiB] | peak after − start-up [MiB] |",
              "|---|---|---|---|---|",
              "| C++, loadMesh + computeTransport (bench_call peak) | %s | %s | %s | %.1f |" % (s3, b3, a3, float(a3) - float(s3)),
              "| Python, prtbake.Mesh.load + transport | %s | %s | %s | %.1f |" % (s1, b, a, float(a) - float(s1)),
              "| Python, the same, then a prtbake.Mesh from NumPy arrays | %s | %s | %s | %.1f |" % (s2, b2, a2, float(a2) - float(s2)),
              "| `prtbake transport` (whole command, writes the .npy) | | %.1f | |" % (int(cli) / 1024), "",
              "Start-up: the resident memory before the mesh is read (Python: after importing numpy and",
              "prtbake). Peak after − start-up is what loading the mesh and the call add: the loader's, the",
              "library's working memory and the output. A copy of the output on its way to NumPy would make",
              "Python's exceed C++'s by the output's size.", ""]
    text = "\n".join(lines) + "\n"
    (ROOT / "bench" / "results" / "python.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
