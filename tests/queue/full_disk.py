#!/usr/bin/python3
"""A full disk under `prtbake queue` (ctest: queue_full_disk).

docs/jobs.md ("Outputs, atomically"): when a write fails, the output's previous version stays
intact, the temporary and staging files are removed, the job is marked failed with the errno's
words, and the queue goes on with the next job file; nothing half-written is renamed into place.

The outputs live on a small tmpfs mounted for the test (the spool directory, the inputs and the
logs stay on the ordinary disk):

1. A first queue run writes small outputs of every writer (OpenEXR scanline and tiled, JSON,
   text, PNG, KTX2, npy) and their manifests there; their bytes are recorded.
2. A filler file leaves two pages free, and job files that rewrite the same outputs with
   parameters that make them larger are submitted, then one whose output lies on the ordinary
   disk. Each rewriting file must end in failed/ with "No space left on device" in its log and
   in its job_end event, the job file after them in done/; the worker exits with 1; every
   previous output and manifest is byte-identical; the tmpfs holds exactly the files it held
   before (no temp or staging file) and has all its free space back.
3. The filler goes, the tmpfs's inodes are used up instead (creating a file fails with ENOSPC),
   and the same is checked for a job whose output file cannot be created and one whose output
   directory cannot be.
4. With space again, strace's fault injection makes single calls fail: EDQUOT on a write of
   the PNG output, EIO on the fsync of the OpenEXR output, and EIO on the fsync of the manifest,
   which the runner writes after the outputs are renamed into place. Each must leave the
   previous outputs and manifest as they were. (The call to fail is found by a traced run of
   the same job file in a scratch directory; the injected run's trace shows that it hit the
   file meant.)

Needs root (to mount) and, for part 4, strace (scripts/packages.sh). It runs in a private mount
namespace (unshare -m) where it can, so that the mount disappears with the test however it ends.
Where no tmpfs can be mounted it exits 77 (ctest's SKIP_RETURN_CODE) and appends the reason to
$PRTBAKE_SKIP_LOG; without strace, part 4 alone is skipped and logged. With PRTBAKE_FORBID_SKIPS=1
(CI) either is a failure instead. Only the Python standard library.
"""
import argparse
import errno
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

NAME = "queue_full_disk"
SKIP_EXIT = 77
NAMESPACE_MARK = "PRTBAKE_FULL_DISK_NAMESPACE"
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SKY = os.path.join(ROOT, "assets", "sky.exr")

TMPFS_BYTES = 2 << 20   # 512 pages: the first run's outputs take about 50
TMPFS_INODES = 64       # the first run's files take about 20
FREE_PAGES = 2          # left by the filler: small staged outputs fit, the larger ones do not
QUEUE_TIMEOUT = 90      # seconds, for one `prtbake queue --drain`

ENOSPC_WORDS = os.strerror(errno.ENOSPC)  # "No space left on device"


def skip(reason):
    line = "%s: %s" % (NAME, reason)
    if os.environ.get("PRTBAKE_FORBID_SKIPS"):
        print("FAILED (PRTBAKE_FORBID_SKIPS is set, and this test would be skipped): " + line)
        sys.exit(1)
    print("SKIPPED: " + line)
    log = os.environ.get("PRTBAKE_SKIP_LOG")
    if log:
        with open(log, "a") as f:  # O_APPEND: whole lines from parallel tests
            f.write(line + "\n")
    sys.exit(SKIP_EXIT)


def skip_part(reason, test):
    """A part that cannot run here: said, logged, and with PRTBAKE_FORBID_SKIPS a failure."""
    line = "%s: partly skipped: %s" % (NAME, reason)
    if os.environ.get("PRTBAKE_FORBID_SKIPS"):
        print("FAIL: %s (PRTBAKE_FORBID_SKIPS is set)" % line)
        test.failures.append(line)
        return
    test.skipped.append(reason)
    print("SKIPPED: " + line)
    log = os.environ.get("PRTBAKE_SKIP_LOG")
    if log:
        with open(log, "a") as f:
            f.write(line + "\n")


def enter_private_namespace():
    """Re-executes this script in a private mount namespace when unshare can make one."""
    if os.environ.get(NAMESPACE_MARK):
        return
    unshare = shutil.which("unshare")
    if not unshare:
        return
    cmd = [unshare, "--mount", "--propagation", "private"]
    if subprocess.run(cmd + ["true"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode != 0:
        return  # no namespace here (a container, say): a plain mount is tried instead
    env = dict(os.environ, **{NAMESPACE_MARK: "1"})
    sys.stdout.flush()
    os.execve(unshare, cmd + [sys.executable, os.path.abspath(__file__)] + sys.argv[1:], env)


# A traced call with a file descriptor, as strace -f -y writes it:
# "PID fsync(3</path>) = -1 EIO (Input/output error) (INJECTED)", the PID left-aligned in five
# columns (a PID below 10000 is followed by two spaces or more). A call that another thread
# interrupted is counted once, by its first half ("... <unfinished ...>"; the second half
# starts "PID <... fsync resumed>" and does not match).
TRACE_LINE = re.compile(r"^(\d+) +(\w+)\((\d+)<([^>]*)>")


def traced_calls(trace_path):
    """The main thread's fsync and write calls in a trace, as (syscall, path, line)."""
    calls, main = [], None
    with open(trace_path, errors="replace") as f:
        for line in f:
            pid = line.split(None, 1)[0] if line.strip() else ""
            if main is None and " execve(" in line:
                main = pid
            m = TRACE_LINE.match(line)
            if m and m.group(1) == main:
                calls.append((m.group(2), m.group(4), line.rstrip("\n")))
    return calls


def write_grid_obj(path, n):
    """A flat (n+1)² vertex grid: transport on it is cheap, its npy grows with the SH order."""
    with open(path, "w") as f:
        for j in range(n + 1):
            for i in range(n + 1):
                f.write("v %.4f 0 %.4f\n" % (2.0 * i / n - 1.0, 2.0 * j / n - 1.0))
        for j in range(n):
            for i in range(n):
                a = j * (n + 1) + i + 1
                b, c = a + 1, a + n + 1
                f.write("f %d %d %d\nf %d %d %d\n" % (a, c, b, b, c, c + 1))


class Test:
    def __init__(self, prtbake, work, fs):
        self.prtbake = prtbake
        self.work = work
        self.fs = fs
        self.spool = os.path.join(work, "spool")
        self.disk_out = os.path.join(work, "disk-out")  # outputs on the ordinary disk
        self.grid = os.path.join(work, "grid.obj")
        self.failures = []
        self.skipped = []  # parts that could not run here
        os.makedirs(os.path.join(self.spool, "pending"))
        write_grid_obj(self.grid, 40)

    # --- helpers -------------------------------------------------------------------------

    def check(self, ok, what, detail=""):
        print(("ok:   " if ok else "FAIL: ") + what + ("" if ok or not detail else "\n      " + detail))
        if not ok:
            self.failures.append(what)
        return ok

    def out(self, name):
        return os.path.join(self.fs, name)

    def submit(self, name, jobs):
        """Writes a job file under a hidden name in pending/ and renames it into place."""
        pending = os.path.join(self.spool, "pending")
        tmp = os.path.join(pending, "." + name + ".tmp")
        with open(tmp, "w") as f:
            json.dump({"jobs": jobs}, f, indent=1)
        os.rename(tmp, os.path.join(pending, name))

    def run_queue(self):
        """One worker, --drain; returns (exit code, job_end events by (job file, id), output)."""
        t0 = time.monotonic()
        try:
            p = subprocess.run([self.prtbake, "queue", self.spool, "--drain", "--log-json"],
                               capture_output=True, text=True, timeout=QUEUE_TIMEOUT)
        except subprocess.TimeoutExpired as e:
            self.check(False, "the queue worker finished within %d s" % QUEUE_TIMEOUT, str(e.stdout))
            return None, {}, ""
        ends = {}
        for line in p.stderr.splitlines():
            if line.startswith("{"):
                try:
                    e = json.loads(line)
                except ValueError:
                    continue
                if e.get("event") == "job_end":
                    ends[(e.get("file"), e.get("id"))] = e
        print("  (queue worker: exit %d, %.1f s)" % (p.returncode, time.monotonic() - t0))
        return p.returncode, ends, p.stdout + p.stderr

    def tmpfs_files(self):
        """Every file and directory on the tmpfs, relative paths."""
        names = set()
        for d, dirs, files in os.walk(self.fs):
            for n in dirs + files:
                names.add(os.path.relpath(os.path.join(d, n), self.fs))
        return names

    def tmpfs_space(self):
        s = os.statvfs(self.fs)
        return s.f_bfree, s.f_ffree

    def snapshot(self):
        """The bytes of every file on the tmpfs, by relative path."""
        snap = {}
        for rel in self.tmpfs_files():
            p = os.path.join(self.fs, rel)
            if os.path.isfile(p):
                with open(p, "rb") as f:
                    snap[rel] = f.read()
        return snap

    def fill_pages(self, path, leave):
        """Writes a filler file that leaves `leave` pages free."""
        s = os.statvfs(self.fs)
        remaining = (s.f_bavail - leave) * s.f_frsize
        chunk = b"\0" * (1 << 20)
        with open(path, "wb") as f:
            while remaining > 0:
                remaining -= f.write(chunk[:min(remaining, len(chunk))])
        return os.statvfs(self.fs).f_bavail

    def fill_inodes(self, prefix):
        """Creates empty files until the tmpfs has no inode left; returns their paths."""
        made = []
        while True:
            p = "%s%03d" % (prefix, len(made))
            try:
                os.close(os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
            except OSError as e:
                if e.errno != errno.ENOSPC:
                    raise
                return made
            made.append(p)

    def check_record(self, name, ids, status, words=None, ends=None):
        """The job file `name` in status/ (done or failed) with its log; for a failed file, each
        job id's "[failed] id: ..." line and job_end event carry `words`."""
        stem = name[:-len(".json")]
        where = os.path.join(self.spool, status)
        self.check(os.path.exists(os.path.join(where, name)), "%s ended in %s/" % (name, status),
                   "done/: %s, failed/: %s" % (sorted(os.listdir(os.path.join(self.spool, "done"))),
                                               sorted(os.listdir(os.path.join(self.spool, "failed")))))
        log_path = os.path.join(where, stem + ".log")
        log = open(log_path).read() if os.path.exists(log_path) else ""
        self.check(log != "", "%s/%s.log exists" % (status, stem))
        for job_id in ids:
            if words is None:
                continue
            lines = [l for l in log.splitlines() if l.startswith("[failed] %s: " % job_id)]
            self.check(any(words in l for l in lines),
                       "%s.log: job '%s' failed with \"%s\"" % (stem, job_id, words),
                       "log:\n" + log)
            e = (ends or {}).get((name, job_id), {})
            self.check(e.get("status") == "failed" and words in e.get("error", ""),
                       "%s: job '%s''s job_end event: failed with \"%s\"" % (name, job_id, words), str(e))
            if lines:
                print("      %s" % lines[0])

    def check_tmpfs_unchanged(self, before, expected_names, space_before, label):
        """Previous outputs and manifests byte-identical, nothing added or left behind, the
        tmpfs's free pages and inodes what they were before the queue ran."""
        changed = [rel for rel, data in before.items()
                   if not os.path.isfile(self.out(rel)) or open(self.out(rel), "rb").read() != data]
        self.check(not changed, "%s: every previous output and manifest is byte-identical (%d files)"
                   % (label, len(before)), "changed or missing: %s" % changed)
        names = self.tmpfs_files()
        leftovers = sorted(n for n in names if ".prtbake-tmp." in n or ".stage." in n)
        self.check(not leftovers, "%s: no temp or staging file left on the tmpfs" % label, str(leftovers))
        self.check(names == expected_names, "%s: the tmpfs holds exactly the files it held before" % label,
                   "added: %s, gone: %s" % (sorted(names - expected_names), sorted(expected_names - names)))
        space = self.tmpfs_space()
        self.check(space == space_before, "%s: the tmpfs's free pages and inodes are as before the run (%d, %d)"
                   % (label, space_before[0], space_before[1]), "now %d pages, %d inodes" % space)

    # --- the passes ----------------------------------------------------------------------

    def first_run(self):
        print("1. small outputs of every writer on the tmpfs")
        o = self.out
        self.first_jobs = [
            {"id": "lut", "type": "lut", "size": 16, "samples": 64,
             "outputs": {"exr": o("lut.exr"), "json": o("lut.json"), "png": o("lut.png")}},
            {"id": "env", "type": "env", "input": SKY, "order": 2,
             "outputs": {"json": o("env.json"), "games202": o("env.txt"), "png": o("env.png")}},
            {"id": "pf", "type": "prefilter", "input": SKY, "size": 16,
             "outputs": {"ktx2": o("pf.ktx2"), "json": o("pf.json")}},
            {"id": "pfx", "type": "prefilter", "input": SKY, "size": 16, "outputs": {"exr": o("pfx.exr")}},
            {"id": "tr", "type": "transport", "input": self.grid, "mode": "unshadowed", "order": 2,
             "samples": 16, "outputs": {"npy": o("tr.npy"), "json": o("tr.json")}},
        ]
        self.submit("10_first.json", self.first_jobs)
        code, ends, output = self.run_queue()
        ok = self.check(code == 0, "first run: the worker exits with 0", output[-3000:])
        self.check_record("10_first.json", [], "done")
        expected = set()
        for j in self.first_jobs:
            outs = list(j["outputs"].values())
            expected.update(os.path.relpath(p, self.fs) for p in outs)
            expected.add(os.path.relpath(outs[0], self.fs) + ".manifest.json")
        names = self.tmpfs_files()
        ok = self.check(names == expected, "first run: every output and manifest is on the tmpfs",
                        "missing: %s, extra: %s" % (sorted(expected - names), sorted(names - expected))) and ok
        self.previous = self.snapshot()
        print("      %d files, %d bytes" % (len(self.previous), sum(map(len, self.previous.values()))))
        return ok

    def full_pages(self):
        print("2. the tmpfs full (%d pages free): larger rewrites of the same outputs" % FREE_PAGES)
        filler = self.out("filler")
        free = self.fill_pages(filler, FREE_PAGES)
        if not self.check(free == FREE_PAGES, "the filler leaves %d pages free" % FREE_PAGES, "%d free" % free):
            return
        space_before = self.tmpfs_space()
        names_before = self.tmpfs_files()
        first = {j["id"]: j for j in self.first_jobs}

        def rewrite(job_id, outputs=None, **params):
            j = dict(first[job_id], **params)
            if outputs is not None:
                j["outputs"] = {k: first[job_id]["outputs"][k] for k in outputs}
            return [j]

        # Each file fails in a different writer; in those with small outputs beside a large one,
        # the small ones are staged before the large one fails and must be removed again.
        failing = [
            ("20_lut_exr.json", rewrite("lut", size=256, samples=16)),          # OpenEXR, 0.5 MB
            ("21_lut_png.json", rewrite("lut", samples=32)),                    # exr, json fit; PNG does not
            ("22_env_json.json", rewrite("env", ["json", "games202"], order=12)),  # JSON, text
            ("23_env_png.json", rewrite("env", order=3)),                       # json, txt fit; PNG does not
            ("24_pf_ktx2.json", rewrite("pf", size=64)),                        # KTX2, 0.26 MB
            ("25_pfx_exr.json", rewrite("pfx", size=64)),                       # tiled OpenEXR
            ("26_tr_npy.json", rewrite("tr", order=8)),                         # npy, 0.43 MB
        ]
        for name, jobs in failing:
            self.submit(name, jobs)
        after = os.path.join(self.disk_out, "after.exr")
        self.submit("90_after.json", [{"id": "after", "type": "lut", "size": 16, "samples": 16,
                                       "outputs": {"exr": after}}])
        code, ends, output = self.run_queue()
        self.check(code == 1, "the worker exits with 1 (a job file failed)", "exit %s\n%s" % (code, output[-3000:]))
        for name, jobs in failing:
            self.check_record(name, [j["id"] for j in jobs], "failed", ENOSPC_WORDS, ends)
        self.check_record("90_after.json", ["after"], "done")
        self.check(os.path.isfile(after) and os.path.isfile(after + ".manifest.json"),
                   "the job file after the failures wrote its output and manifest")
        self.check_tmpfs_unchanged(self.previous, names_before, space_before, "full pages")
        os.unlink(filler)

    def full_inodes(self):
        print("3. the tmpfs out of inodes: an output file and an output directory cannot be created")
        fillers = self.fill_inodes(self.out("inode-"))
        space_before = self.tmpfs_space()
        if not self.check(space_before[1] == 0, "no inode left (%d empty files)" % len(fillers),
                          "%d inodes free" % space_before[1]):
            return
        names_before = self.tmpfs_files()
        lut = dict(self.first_jobs[0], samples=48, outputs={"exr": self.out("lut.exr")})
        self.submit("30_inode_file.json", [lut])
        self.submit("31_inode_dir.json", [{"id": "newdir", "type": "lut", "size": 16, "samples": 16,
                                           "outputs": {"exr": self.out("newdir/lut.exr")}}])
        after = os.path.join(self.disk_out, "after2.exr")
        self.submit("91_after.json", [{"id": "after2", "type": "lut", "size": 16, "samples": 16,
                                       "outputs": {"exr": after}}])
        code, ends, output = self.run_queue()
        self.check(code == 1, "the worker exits with 1 (a job file failed)", "exit %s\n%s" % (code, output[-3000:]))
        self.check_record("30_inode_file.json", ["lut"], "failed", ENOSPC_WORDS, ends)
        self.check_record("31_inode_dir.json", ["newdir"], "failed", ENOSPC_WORDS, ends)
        self.check_record("91_after.json", ["after2"], "done")
        self.check(os.path.isfile(after), "the job file after the failures wrote its output")
        self.check_tmpfs_unchanged(self.previous, names_before, space_before, "no inodes")
        for p in fillers:
            os.unlink(p)

    def run_traced(self, spool, trace, inject=None):
        """A queue worker under strace (fsync and write of every thread, paths of fds);
        `inject`: (syscall, errno name, n) fails the main thread's n-th such call."""
        cmd = [self.strace, "-f", "-qq", "-y", "-s", "0", "--seccomp-bpf", "-o", trace,
               "-e", "trace=execve,fsync,write"]
        if inject:
            cmd += ["-e", "inject=%s:error=%s:when=%d" % inject]
        try:
            p = subprocess.run(cmd + [self.prtbake, "queue", spool, "--drain", "--log-json"],
                               capture_output=True, text=True, timeout=QUEUE_TIMEOUT)
        except subprocess.TimeoutExpired:
            self.check(False, "the traced queue worker finished within %d s" % QUEUE_TIMEOUT)
            return None, {}, ""
        ends = {}
        for line in p.stderr.splitlines():
            if line.startswith("{") and '"job_end"' in line:
                e = json.loads(line)
                ends[(e.get("file"), e.get("id"))] = e
        return p.returncode, ends, p.stdout + p.stderr

    def injected(self):
        print("4. single calls failed by strace: EDQUOT on a write, EIO on an fsync")
        self.strace = shutil.which("strace")
        if not self.strace:
            skip_part("strace is not installed (the injected EDQUOT and EIO)", self)
            return
        probe = subprocess.run([self.strace, "-f", "-qq", "-o", os.devnull, "-e",
                                "inject=fsync:error=EIO:when=1", "true"], capture_output=True, text=True)
        if probe.returncode != 0:
            skip_part("strace cannot trace here: " + probe.stderr.strip(), self)
            return
        lut = self.first_jobs[0]
        rewrite = dict(lut, samples=40)  # the same outputs, new parameters: it must run

        # The calls to fail, from a traced run of the same rewrite in a scratch directory that
        # holds what the tmpfs holds (the first version), after one run to warm PoCL's cache.
        scratch = os.path.join(self.work, "calibrate")
        spool = os.path.join(scratch, "spool")
        os.makedirs(os.path.join(spool, "pending"))

        def scratch_job(job):
            j = dict(job)
            j["outputs"] = {k: os.path.join(scratch, os.path.basename(v)) for k, v in job["outputs"].items()}
            return j

        def submit(name, job):
            p = os.path.join(spool, "pending", name)
            with open(p + ".tmp", "w") as f:
                json.dump({"jobs": [job]}, f)
            os.rename(p + ".tmp", p)

        for i, job in enumerate([lut, rewrite, lut]):
            submit("%d.json" % i, scratch_job(job))
            subprocess.run([self.prtbake, "queue", spool, "--drain", "--quiet"], capture_output=True,
                           timeout=QUEUE_TIMEOUT)
        submit("3.json", scratch_job(rewrite))
        trace = os.path.join(self.work, "calibrate.trace")
        code, _, output = self.run_traced(spool, trace)
        if not self.check(code == 0, "the traced scratch run of the rewrite succeeds", output[-2000:]):
            return
        calls = traced_calls(trace)

        def nth(syscall, wanted):
            """The 1-based index of the first main-thread `syscall` on a file `wanted` accepts (its path)."""
            k = 0
            for name, path, _ in calls:
                if name == syscall:
                    k += 1
                    if wanted(path):
                        return k
            return None

        # A job's outputs are written in staging directories (".stage.prtbake-tmp.<pid>.<n>/"),
        # each through a temp file ".<name>.prtbake-tmp.<pid>.<n>".
        def staged(p, ext):
            return "/.stage.prtbake-tmp." in p and os.path.basename(p).startswith(".lut" + ext + ".prtbake-tmp.")
        cases = [
            ("40_edquot_png.json", "write", "EDQUOT", errno.EDQUOT, "a write of the PNG output",
             lambda p: staged(p, ".png")),
            ("41_eio_exr.json", "fsync", "EIO", errno.EIO, "the fsync of the OpenEXR output",
             lambda p: staged(p, ".exr")),
            ("42_eio_manifest.json", "fsync", "EIO", errno.EIO, "the fsync of the new manifest (after the "
             "outputs' rename)", lambda p: os.path.basename(p).startswith(".lut.exr.manifest.json.prtbake-tmp.")),
        ]
        for name, syscall, err, code_errno, what, wanted in cases:
            print("   %s: %s fails with %s" % (name, what, err))
            n = nth(syscall, wanted)
            if not self.check(n is not None, "%s: the scratch run's trace has %s" % (name, what)):
                continue
            names_before, space_before = self.tmpfs_files(), self.tmpfs_space()
            self.submit(name, [rewrite])
            trace = os.path.join(self.work, name + ".trace")
            code, ends, output = self.run_traced(self.spool, trace, (syscall, err, n))
            hit = [path for sc, path, line in traced_calls(trace) if line.endswith("(INJECTED)")]
            self.check(len(hit) == 1 and wanted(hit[0]),
                       "%s: the injected %s hit %s" % (name, err, what), "hit: %s" % hit)
            self.check(code == 1, "%s: the worker exits with 1" % name, "exit %s\n%s" % (code, output[-3000:]))
            self.check_record(name, ["lut"], "failed", os.strerror(code_errno), ends)
            self.check_tmpfs_unchanged(self.previous, names_before, space_before, name)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--prtbake", required=True, help="the prtbake executable")
    ap.add_argument("--keep", action="store_true", help="keep the spool directory and logs")
    args = ap.parse_args()
    prtbake = os.path.abspath(args.prtbake)
    if not os.access(prtbake, os.X_OK):
        print("FAIL: %s is not an executable" % prtbake)
        return 1
    if os.geteuid() != 0:
        skip("not root, cannot mount a tmpfs")
    enter_private_namespace()
    os.environ.setdefault("PRTBAKE_DEVICE", "cpu")

    t0 = time.monotonic()
    work = tempfile.mkdtemp(prefix="prtbake-full-disk-")
    fs = os.path.join(work, "fs")
    os.mkdir(fs)
    opts = "size=%d,nr_inodes=%d,mode=0755" % (TMPFS_BYTES, TMPFS_INODES)
    try:
        m = subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "prtbake-full-disk", fs],
                           capture_output=True, text=True)
        reason = m.stderr.strip() or "exit %d" % m.returncode
    except OSError as e:
        m, reason = None, str(e)
    if m is None or m.returncode != 0:
        shutil.rmtree(work, ignore_errors=True)
        skip("cannot mount a tmpfs: " + reason)

    test = None
    try:
        print("tmpfs (%s) on %s; %s" % (opts, fs, "private mount namespace" if os.environ.get(NAMESPACE_MARK)
                                         else "mounted in the current namespace"))
        test = Test(prtbake, work, fs)
        if test.first_run():
            test.full_pages()
            test.full_inodes()
            test.injected()
        else:
            print("the first run failed: nothing to compare against")
    finally:
        u = subprocess.run(["umount", fs], capture_output=True, text=True)
        if u.returncode != 0:
            subprocess.run(["umount", "-l", fs], capture_output=True, text=True)
        if test is not None and (test.failures or args.keep):
            print("kept for inspection: %s (the tmpfs is unmounted)" % work)
        else:
            shutil.rmtree(work, ignore_errors=True)
    print("%.1f s" % (time.monotonic() - t0))
    if test.failures:
        print("%d check(s) failed:" % len(test.failures))
        for f in test.failures:
            print("  " + f)
        return 1
    print("all checks passed" + ("" if not test.skipped else "; skipped: " + "; ".join(test.skipped)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
