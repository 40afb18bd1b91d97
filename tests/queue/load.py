#!/usr/bin/python3
"""Load test of `prtbake queue` with faults (docs/jobs.md, "prtbake queue").

A pool of workers (default 4) works through a spool directory while job files keep arriving (a
tenth before the workers start, the rest in waves; each written elsewhere or under a hidden name
and renamed into pending/). Workers are killed at random with SIGKILL, mostly while they hold a
claim, and replaced at once; a worker holding a claim is paused with SIGSTOP for longer than
--stale-after, until another worker has taken its claim back, then continued (it finishes that
file while the other worker runs it again; it is not killed before it has). At the end the pool is
killed and one `--drain` worker takes back the claims and finishes what is left. A few job files
hold an invalid job on purpose. Then it checks what the queue promises:

- every job file is in exactly one of done/ or failed/, once (a reclaimed copy,
  <stem>.reclaimed-<pid>.json, counts as the file), in the right one (failed/ for the invalid
  ones), each with its log, and no run of a valid file failed; nothing is left in pending/ or
  running/;
- every output exists and equals the output of a reference `prtbake run` of the same job files;
  every job has its manifest, whose sizes match the outputs, and a dry run finds every job of
  done/ up to date;
- no temp or staging file (a name containing `.prtbake-tmp.`) is left in the output tree or the
  spool.

Only the Python standard library; run with Debian's /usr/bin/python3. Exit code 0 when every
check holds, 1 (with one line per violation) otherwise. An overall deadline (--deadline) kills
every worker and fails instead of hanging.

    /usr/bin/python3 tests/queue/load.py --prtbake build/prtbake --files 120 [--json figures.json]
"""
import argparse
import collections
import hashlib
import json
import os
import random
import re
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
TEMP_MARKER = ".prtbake-tmp."
# A job file in done/ or failed/: its name, or the name a reclaim gave it when pending/ already
# held one of that name (service/cmd_queue.cpp: <stem>.reclaimed-<pid>.json).
DONE_NAME = re.compile(r"(.+?)((?:\.reclaimed-\d+)*)\.json")
# The order in which the runner picks the output that names the manifest (docs/jobs.md,
# "Manifests and incremental runs").
MANIFEST_KIND = {"lut": ["exr"], "env": ["json", "games202", "png"]}
EXTENSION = {"exr": ".exr", "json": ".json", "png": ".png", "games202": ".txt"}
# Outputs compared with the reference run's: EXR, PNG and the games202 text are byte-identical
# run to run on one device (same parameters and kernels, a fixed order of summation). A JSON
# sidecar is compared as canonical JSON without the keys that differ from run to run of the same
# job (the product's timings); the absolute paths it holds are taken relative to each tree.
# Manifests (timings, finish time) are not compared but checked against the outputs.
VOLATILE_KEYS = {"timings", "timings_seconds"}


# The figures of --json, in this order. kills: SIGKILLs while the pool works (each followed by a
# restart); end_kills, sigterms: how the pool was stopped at the end; wall_seconds: from the first
# worker's start to the end of the --drain worker; jobs_per_minute: every job of every file over
# that time.
FIGURES = ["seed", "jobs", "job_files", "failing_files", "workers", "stale_after", "kill_every",
           "kills", "kills_holding_claim", "restarts", "pauses", "pauses_reclaimed", "pause_seconds_max", "end_kills",
           "sigterms",
           "wall_seconds", "jobs_per_minute", "reference_seconds", "left_for_drain",
           "lost", "duplicated", "wrong_place", "mismatched", "missing_outputs", "bad_manifests", "temp_files_left",
           "not_up_to_date", "reruns", "reclaims_dead_worker", "reclaims_no_sign_of_life", "stale_finishes",
           "temp_files_swept", "total_seconds", "violations"]


class Violations(list):
    def add(self, message):
        self.append(message)
        print("load.py: VIOLATION: " + message, flush=True)


def log(message):
    print("load.py: " + message, flush=True)


# ----- inputs, job files and the reference ------------------------------------------------

def write_hdr(path, width, height, rng):
    """A small lat-long Radiance HDR (2:1), flat (uncompressed) scanlines of smooth colours."""
    base = [rng.uniform(0.2, 2.0) for _ in range(3)]
    with open(path, "wb") as f:
        f.write(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (height, width))
        for y in range(height):
            for x in range(width):
                rgb = [b * (1.0 + 0.8 * ((x * (c + 1) + y * 3) % width) / width) for c, b in enumerate(base)]
                m = max(rgb)
                e = 0
                while m >= 1.0:
                    m /= 2.0
                    e += 1
                while m < 0.5:
                    m *= 2.0
                    e -= 1
                scale = 256.0 / 2.0 ** e
                # The first byte of a flat scanline must not be 2 (that starts a run-length one).
                f.write(struct.pack("4B", *[max(3, min(255, int(v * scale))) for v in rgb], e + 128))


def make_job_file(rng, stem, inputs, failing, groups):
    """One job file of 1 to 3 cheap jobs (lut, env). Returns (text, jobs); jobs lists, per job,
    its type, whether it is valid, and its outputs as (kind, path relative to the spool's parent).
    A failing file holds an env job whose input does not exist (refused at validation) beside
    valid jobs, so it must end in failed/ while its valid jobs still write their outputs."""
    group = "d%02d" % rng.randrange(groups)  # job files share output directories
    jobs, spec = [], []
    count = rng.randint(1, 3)
    bad = rng.randrange(count) if failing else -1
    for k in range(count):
        kind = "lut" if rng.random() < 0.6 else "env"
        if k == bad:
            kind = "env"
        job_id = "%s%d" % (kind, k)
        j = {"id": job_id, "type": kind}
        if kind == "lut":
            j["size"] = rng.randint(8, 16)
            j["samples"] = rng.randint(16, 64)
            if rng.random() < 0.2:
                j["ndf"] = "beckmann"
            if rng.random() < 0.2:
                j["multiscatter"] = True
            if rng.random() < 0.2:
                j["half"] = True
            kinds = ["exr"] + (["json"] if rng.random() < 0.5 else []) + (["png"] if rng.random() < 0.1 else [])
        else:
            j["input"] = "missing-%s.hdr" % stem if k == bad else rng.choice(inputs)
            j["order"] = rng.randint(1, 6)
            j["quantity"] = rng.choice(["radiance", "irradiance", "irradiance_over_pi"])
            if rng.random() < 0.3:
                j["window"] = "hann"
            kinds = rng.choice([["json"], ["games202"], ["json", "games202"]]) + (["png"] if rng.random() < 0.1 else [])
        outs = [(c, "out/%s/%s-%s%s" % (group, stem, job_id, EXTENSION[c])) for c in kinds]
        # Relative paths resolve against DIR/pending (the reference: its own copy of that tree).
        j["outputs"] = {c: "../../" + p for c, p in outs}
        spec.append(j)
        jobs.append({"id": job_id, "type": kind, "valid": k != bad, "outputs": outs})
    return json.dumps({"jobs": spec}, indent=1) + "\n", jobs


def strip_volatile(obj):
    if isinstance(obj, dict):
        return {k: strip_volatile(v) for k, v in obj.items() if k not in VOLATILE_KEYS}
    if isinstance(obj, list):
        return [strip_volatile(v) for v in obj]
    return obj


def digest(path, tree):
    """SHA-256 of an output of the tree rooted at tree (see VOLATILE_KEYS); a JSON sidecar names
    the outputs by their absolute paths, compared here relative to the tree."""
    with open(path, "rb") as f:
        data = f.read()
    if path.endswith(".json"):
        data = data.replace(os.path.join(tree, "out", "").encode(), b"out/")
        data = json.dumps(strip_volatile(json.loads(data)), sort_keys=True).encode()
    return hashlib.sha256(data).hexdigest()


# ----- workers --------------------------------------------------------------------------

class Worker:
    def __init__(self, args, spool, logdir, number, drain=False):
        self.log_path = os.path.join(logdir, "worker-%03d%s.log" % (number, "-drain" if drain else ""))
        self.log_file = open(self.log_path, "wb")
        cmd = [args.prtbake, "queue", spool, "--poll", str(args.poll), "--stale-after", str(args.stale_after),
               "--quiet", "--log-json"] + (["--drain"] if drain else [])
        self.proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=self.log_file, stderr=subprocess.STDOUT)
        self.pid = self.proc.pid
        self.paused = False
        self.killed = False
        self.stale_file = None  # after a pause: the file it held, until it reports that file finished
        self.read_at = 0

    def claim(self, running):
        """This worker's claim in running/ (<name>.<host>.<pid>), or None."""
        suffix = "." + str(self.pid)
        for c in running:
            if c.endswith(suffix) and ".json." in c:
                return c
        return None

    def new_events(self):
        with open(self.log_path, "rb") as f:
            f.seek(self.read_at)
            data = f.read()
        end = data.rfind(b"\n") + 1
        self.read_at += end
        return parse_events(data[:end].decode("utf-8", "replace"))

    def signal(self, sig):
        try:
            os.kill(self.pid, sig)
        except ProcessLookupError:
            pass

    def close(self):
        self.log_file.close()


def parse_events(text):
    events = []
    for line in text.splitlines():
        if line.startswith("{"):
            try:
                events.append(json.loads(line))
            except ValueError:
                events.append({"event": "unparsed", "line": line})
        else:
            events.append({"event": "text", "line": line})
    return events


def claimed_name(claim):
    """The job file of a claim: <name>.json.<host>.<pid> (service/cmd_queue.cpp parses it so)."""
    return claim[:claim.rfind(".json.") + 5]


def listdir(path):
    try:
        return sorted(os.listdir(path))
    except FileNotFoundError:
        return []


# ----- the run ----------------------------------------------------------------------------

def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    build = os.environ.get("PRTBAKE_BUILD_DIR") or os.path.join(ROOT, "build")
    ap.add_argument("--prtbake", default=os.path.join(build, "prtbake"),
                    help="the command (default: $PRTBAKE_BUILD_DIR/prtbake, else build/prtbake)")
    ap.add_argument("--files", type=int, default=120, help="job files (default 120)")
    ap.add_argument("--seed", type=int, default=None,
                    help="random seed of the job files and the faults (default: from the clock; printed)")
    ap.add_argument("--workers", type=int, default=4, help="workers kept alive (default 4)")
    ap.add_argument("--kill-every", type=float, default=1.0,
                    help="mean seconds between SIGKILLs of a random worker (default 1; 0: none)")
    ap.add_argument("--pauses", type=int, default=1, help="SIGSTOP pauses past --stale-after (default 1)")
    ap.add_argument("--stale-after", type=float, default=3.0, help="the workers' --stale-after (default 3)")
    ap.add_argument("--poll", type=float, default=0.05, help="the workers' --poll (default 0.05)")
    ap.add_argument("--failing", type=int, default=None,
                    help="job files with an invalid job, which must end in failed/ (default: files/50, at least 1)")
    ap.add_argument("--drain-share", type=float, default=0.1,
                    help="about this share of the files is left for the --drain worker (default 0.1)")
    ap.add_argument("--deadline", type=float, default=600.0,
                    help="seconds after which every worker is killed and the test fails (default 600)")
    ap.add_argument("--keep", action="store_true", help="keep the temp directory (it is also kept on failure)")
    ap.add_argument("--json", metavar="FILE", help="write the figures to FILE")
    args = ap.parse_args()
    if args.files < 1 or args.workers < 1 or args.stale_after < 1:
        ap.error("--files, --workers and --stale-after must be at least 1")
    if args.pauses > 0 and args.workers < 2:
        ap.error("--pauses needs at least 2 workers (another one takes the claim back)")
    args.prtbake = os.path.abspath(args.prtbake)
    if not os.access(args.prtbake, os.X_OK):
        print("load.py: %s is not an executable" % args.prtbake, file=sys.stderr)
        return 1
    seed = args.seed if args.seed is not None else int(time.time() * 1000) % 1000000
    rng = random.Random(seed)
    failing = args.failing if args.failing is not None else max(1, args.files // 50)
    failing = min(failing, args.files)
    t_begin = time.monotonic()
    deadline = t_begin + args.deadline

    def left():
        return deadline - time.monotonic()

    signal.signal(signal.SIGTERM, lambda sig, frame: sys.exit(128 + sig))  # the workers are killed on the way out
    tmp = tempfile.mkdtemp(prefix="prtbake-queue-load-")
    log("seed %d, %d job files (%d failing on purpose), %d workers, --stale-after %g, kill every %g s, in %s"
        % (seed, args.files, failing, args.workers, args.stale_after, args.kill_every, tmp))
    violations = Violations()
    workers, everyone = [], []
    figures, counts = collections.OrderedDict(), collections.Counter()
    try:
        run(args, rng, seed, failing, tmp, left, violations, workers, everyone, figures, counts)
    except DeadlineExceeded as e:
        violations.add("deadline of %g s exceeded (%s); every worker killed" % (args.deadline, e))
    finally:
        for w in everyone:  # whatever is still running, whatever happened
            if w.proc.poll() is None:
                w.signal(signal.SIGCONT)
                w.signal(signal.SIGKILL)
                w.proc.wait()
            w.close()
    for key in ("kills", "kills_holding_claim", "restarts", "end_kills", "sigterms", "pauses", "pauses_reclaimed"):
        figures[key] = counts[key]
    figures["pause_seconds_max"] = round(counts["pause_seconds_max"], 2)
    figures["total_seconds"] = round(time.monotonic() - t_begin, 2)
    figures["violations"] = list(violations)
    if args.json:
        ordered = collections.OrderedDict((k, figures[k]) for k in FIGURES if k in figures)
        ordered.update(figures)
        with open(args.json, "w") as f:
            json.dump(ordered, f, indent=1)
            f.write("\n")
    summary = ("%s: %d jobs in %d job files, %d workers, %d kills, %d restarts, %d pauses"
               % ("FAILED" if violations else "ok", figures.get("jobs", 0), args.files, args.workers,
                  figures["kills"], figures["restarts"], figures["pauses"]))
    if "wall_seconds" in figures:
        summary += ", %.1f s, %.0f jobs/min" % (figures["wall_seconds"], figures["jobs_per_minute"])
    if "lost" in figures:
        summary += ("; lost %d, duplicated %d, mismatched %d, temp files left %d"
                    % (figures["lost"], figures["duplicated"], figures["mismatched"], figures["temp_files_left"]))
    else:
        summary += "; not checked"
    print(summary, flush=True)
    if violations:
        print("load.py: %d violation(s); seed %d; kept for inspection: %s" % (len(violations), seed, tmp), file=sys.stderr)
        return 1
    if args.keep:
        log("kept: " + tmp)
    else:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


class DeadlineExceeded(Exception):
    pass


def run(args, rng, seed, failing, tmp, left, violations, workers, everyone, figures, counts):
    spool = os.path.join(tmp, "spool")
    pending, running, done, failed = (os.path.join(spool, d) for d in ("pending", "running", "done", "failed"))
    for d in (pending, running, done, failed):
        os.makedirs(d)
    incoming = os.path.join(tmp, "incoming")  # job files are written here, or in pending/ under a hidden name
    refdir = os.path.join(tmp, "ref")
    ref_pending = os.path.join(refdir, "spool", "pending")
    logdir = os.path.join(tmp, "logs")
    indir = os.path.join(tmp, "inputs")
    for d in (incoming, ref_pending, logdir, indir):
        os.makedirs(d)

    # Inputs (absolute paths, shared by both trees) and job files.
    inputs = []
    for k, (w, h) in enumerate([(16, 8), (32, 16), (24, 12)]):
        p = os.path.join(indir, "sky%d.hdr" % k)
        write_hdr(p, w, h, rng)
        inputs.append(p)
    prefixes = ["f", "bake.", "lut-", "a.json."]  # a claim name is parsed from its last ".json."
    names = ["%s%04d.json" % (rng.choice(prefixes), i) for i in range(args.files)]
    failing_names = set(rng.sample(names, failing))
    groups = max(4, args.files // 25)
    texts, jobs_of = {}, {}
    for name in names:
        texts[name], jobs_of[name] = make_job_file(rng, name[:-5], inputs, name in failing_names, groups)
        with open(os.path.join(ref_pending, name), "w") as f:
            f.write(texts[name])
    n_jobs = sum(len(j) for j in jobs_of.values())
    figures.update([("seed", seed), ("jobs", n_jobs), ("job_files", args.files), ("failing_files", failing),
                    ("workers", args.workers), ("stale_after", args.stale_after), ("kill_every", args.kill_every)])

    # The reference: every job file once, by one `prtbake run`.
    t0 = time.monotonic()
    try:
        ref = subprocess.run([args.prtbake, "run"] + [os.path.join(ref_pending, n) for n in names] + ["--quiet"],
                             stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=max(1.0, left()))
    except subprocess.TimeoutExpired:
        raise DeadlineExceeded("in the reference run")
    ref_seconds = time.monotonic() - t0
    figures["reference_seconds"] = round(ref_seconds, 2)
    if ref.returncode != (1 if failing else 0):
        violations.add("the reference `prtbake run` exited with %d: %s" % (ref.returncode, ref.stderr.strip()[-2000:]))
    expected = {}  # output path relative to the tree → digest
    for name in names:
        for job in jobs_of[name]:
            if not job["valid"]:
                continue
            for kind, rel in job["outputs"]:
                p = os.path.join(refdir, rel)
                if not os.path.isfile(p):
                    violations.add("the reference run did not write %s" % rel)
                    continue
                expected[rel] = digest(p, refdir)
    if violations:
        return
    log("reference: %d jobs in %.1f s (one `prtbake run`), %d outputs" % (n_jobs, ref_seconds, len(expected)))

    # Submission: a first wave before the workers start, the rest in waves while they run, over
    # about 60 % of the time one process took for everything.
    order = names[:]
    rng.shuffle(order)
    first = max(1, len(order) // 10)
    rest = order[first:]
    span = max(2.0, 0.6 * ref_seconds)
    waves = []
    n_waves = max(4, len(rest) // 8)
    cuts = sorted(rng.sample(range(1, len(rest)), min(n_waves - 1, max(0, len(rest) - 1)))) if len(rest) > 1 else []
    bounds = [0] + cuts + [len(rest)]
    for k in range(len(bounds) - 1):
        if bounds[k] < bounds[k + 1]:
            waves.append((span * (k + rng.random()) / (len(bounds) - 1), rest[bounds[k]:bounds[k + 1]]))
    def submit(batch):
        for name in batch:
            if rng.random() < 0.5:
                staged = os.path.join(pending, "." + name + ".part")  # hidden: ignored by workers
            else:
                staged = os.path.join(incoming, name)
            with open(staged, "w") as f:
                f.write(texts[name])
            os.rename(staged, os.path.join(pending, name))

    submit(order[:first])
    number = [0]

    def start_worker():
        number[0] += 1
        w = Worker(args, spool, logdir, number[0])
        workers.append(w)
        everyone.append(w)
        return w

    def check_deadline(what):
        if left() <= 0:
            raise DeadlineExceeded(what)

    t_queue = time.monotonic()
    for _ in range(args.workers):
        start_worker()
    next_kill = t_queue + rng.expovariate(1.0 / args.kill_every) if args.kill_every > 0 else float("inf")
    pause_at = [t_queue + span * (k + 1) / (args.pauses + 1) for k in range(args.pauses)]
    paused = []  # (worker, claim, time stopped)
    pause_limit = args.stale_after + 10.0  # a claim not taken back by then is a violation

    def finished_files():
        return sum(1 for d in (done, failed) for n in listdir(d) if n.endswith(".json"))

    while True:
        check_deadline("while the workers ran")
        now = time.monotonic() - t_queue
        # The last wave waits until the pauses are over, so that the --drain worker has work too.
        while waves and waves[0][0] <= now and (len(waves) > 1 or not (pause_at or paused)):
            submit(waves.pop(0)[1])
        run_names = listdir(running)

        # Workers that ended without being asked to: a worker without --drain runs until signalled.
        for w in list(workers):
            if w.proc.poll() is not None:
                violations.add("worker %d exited by itself with %d (see %s)" % (w.pid, w.proc.returncode, w.log_path))
                workers.remove(w)
                start_worker()
                counts["restarts"] += 1
            elif w.stale_file:
                for e in w.new_events():
                    if e.get("event") == "finished" and e.get("file") == w.stale_file:
                        w.stale_file = None

        # Pauses: SIGSTOP a worker holding a claim; SIGCONT once another worker has taken the claim
        # back (a claim idle for longer than --stale-after) and at least --stale-after + 1 s later.
        # Pauses may overlap; one worker at least is never paused.
        if pause_at and time.monotonic() >= pause_at[0] and len(paused) < args.workers - 1:
            holders = [(w, w.claim(run_names)) for w in workers if not w.paused and not w.stale_file]
            holders = [(w, c) for w, c in holders if c]
            if holders:
                w, c = rng.choice(holders)
                w.signal(signal.SIGSTOP)
                w.paused = True
                if os.path.exists(os.path.join(running, c)):
                    paused.append((w, c, time.monotonic()))
                    pause_at.pop(0)
                    counts["pauses"] += 1
                else:  # it finished that file just now: let it go on, try again
                    w.signal(signal.SIGCONT)
                    w.paused = False
            elif not any(n.endswith(".json") and not n.startswith(".") for n in listdir(pending)):
                if waves:  # nothing to pause a worker on: the next wave now
                    submit(waves.pop(0)[1])
                elif finished_files() >= args.files:
                    violations.add("%d pause(s) not done: every file was finished (too few files)" % len(pause_at))
                    pause_at.clear()
        for p in list(paused):
            w, c, t_stop = p
            held = os.path.exists(os.path.join(running, c))
            long_enough = time.monotonic() - t_stop > args.stale_after + 1.0
            if (not held and long_enough) or time.monotonic() - t_stop > pause_limit:
                if held:
                    violations.add("worker %d was paused for %.1f s holding %s (--stale-after %g) and no other worker "
                                   "took the claim back" % (w.pid, time.monotonic() - t_stop, c, args.stale_after))
                else:
                    counts["pauses_reclaimed"] += 1
                counts["pause_seconds_max"] = max(counts["pause_seconds_max"], time.monotonic() - t_stop)
                w.signal(signal.SIGCONT)
                w.paused = False
                # Not killed until it has finished that file: it still writes that file's outputs,
                # and nothing would run there again to sweep its staging files.
                w.stale_file = claimed_name(c)
                paused.remove(p)

        # Kills: SIGKILL a random worker (mostly one holding a claim), reap it, start another.
        if time.monotonic() >= next_kill:
            alive = [w for w in workers if not w.paused and not w.stale_file]
            holding = [w for w in alive if w.claim(run_names)]
            pool = holding if holding and rng.random() < 0.8 else alive
            if pool:
                w = rng.choice(pool)
                if w.claim(run_names):
                    counts["kills_holding_claim"] += 1
                w.signal(signal.SIGKILL)
                w.proc.wait()  # reaped: a zombie would still look alive to the other workers
                w.killed = True
                workers.remove(w)
                counts["kills"] += 1
                start_worker()
                counts["restarts"] += 1
            next_kill = time.monotonic() + rng.expovariate(1.0 / args.kill_every)

        if not waves and not pause_at and not paused:
            if finished_files() >= args.files * (1.0 - args.drain_share):
                break
        time.sleep(0.05)

    # The end: the pool stops (SIGKILL, except workers still finishing a file they held while
    # paused: SIGTERM, which finishes the current file), then one --drain worker takes back the
    # dead workers' claims and finishes everything.
    for w in list(workers):
        if w.stale_file:
            w.signal(signal.SIGTERM)
            counts["sigterms"] += 1
        else:
            w.signal(signal.SIGKILL)
            w.killed = True
            counts["end_kills"] += 1
    for w in list(workers):
        try:
            w.proc.wait(timeout=max(1.0, min(60.0, left())))
        except subprocess.TimeoutExpired:
            violations.add("worker %d did not stop within 60 s of SIGTERM" % w.pid)
            w.signal(signal.SIGKILL)
            w.proc.wait()
        if not w.killed and w.proc.returncode not in (0, 1):
            violations.add("worker %d exited with %d after SIGTERM" % (w.pid, w.proc.returncode))
    workers.clear()
    figures["left_for_drain"] = args.files - finished_files()
    check_deadline("when the pool stopped")
    drain = Worker(args, spool, logdir, number[0] + 1, drain=True)
    everyone.append(drain)
    try:
        drain.proc.wait(timeout=max(1.0, left()))
    except subprocess.TimeoutExpired:
        raise DeadlineExceeded("while the --drain worker ran")
    wall = time.monotonic() - t_queue
    drain_failed = [e for e in drain.new_events() if e.get("event") == "finished" and e.get("status") != "done"]
    if drain.proc.returncode not in (0, 1) or (drain.proc.returncode == 1) != bool(drain_failed):
        violations.add("the --drain worker exited with %d (%d failed files; see %s)"
                       % (drain.proc.returncode, len(drain_failed), drain.log_path))
    log("queue: %.1f s; %d files were left for the --drain worker" % (wall, figures["left_for_drain"]))

    figures["wall_seconds"] = round(wall, 2)
    figures["jobs_per_minute"] = round(n_jobs / wall * 60.0, 1)
    t0 = time.monotonic()
    check(args, names, jobs_of, failing_names, expected, tmp, spool, logdir, violations, figures, left)
    log("checked in %.1f s" % (time.monotonic() - t0))


# ----- the checks ---------------------------------------------------------------------------

def check(args, names, jobs_of, failing_names, expected, tmp, spool, logdir, violations, figures, left):
    known = set(names)
    # The spool.
    for d in ("pending", "running"):
        for n in listdir(os.path.join(spool, d)):
            violations.add("%s/%s is left over" % (d, n))
    where = collections.defaultdict(list)  # job file → ["done/<name>", ...]
    logs = {}
    for d in ("done", "failed"):
        for n in listdir(os.path.join(spool, d)):
            if n.endswith(".log"):
                with open(os.path.join(spool, d, n), errors="replace") as f:
                    logs[d + "/" + n] = f.read()
                continue
            m = DONE_NAME.fullmatch(n)
            if not m or m.group(1) + ".json" not in known:
                violations.add("%s/%s: not a job file that was submitted" % (d, n))
                continue
            where[m.group(1) + ".json"].append(d + "/" + n)
    lost = wrong = 0
    duplicated = set()
    for name in names:
        places = where.get(name, [])
        if not places:
            lost += 1
            violations.add("%s is lost: in neither done/ nor failed/" % name)
        elif len(places) > 1:
            duplicated.add(name)
            violations.add("%s is duplicated: %s" % (name, ", ".join(places)))
        want = "failed" if name in failing_names else "done"
        for p in places:
            if not p.startswith(want + "/"):
                wrong += 1
                violations.add("%s ended in %s, expected in %s/" % (name, p, want))
            if p[:-5] + ".log" not in logs:
                violations.add("%s has no log %s.log" % (p, p[:-5]))
    # The logs: how often each file ran to the end, and whether a run of a valid file failed
    # (a worker that was paused finishes its file after another worker ran it too: its log goes
    # to the same log file, and it must not fail).
    runs = collections.Counter()
    for path, text in logs.items():
        m = DONE_NAME.fullmatch(os.path.basename(path)[:-4] + ".json")
        name = m.group(1) + ".json" if m else None
        if name not in known:
            violations.add("%s: a log of no submitted job file" % path)
            continue
        runs[name] += text.count("\nfinished ") + text.startswith("finished ")
        if path.startswith("failed/") and name not in failing_names:
            violations.add("%s: a run of a valid job file failed:\n%s" % (path, text.strip()[-1500:]))
    figures["reruns"] = sum(max(0, runs[n] - 1) for n in names)
    # Worker events: reclaims, swept temp files, files finished after their claim was taken back.
    reclaims = collections.Counter()
    swept = stale_finishes = 0
    moves = collections.Counter()
    for n in listdir(logdir):
        with open(os.path.join(logdir, n), errors="replace") as f:
            events = parse_events(f.read())
        unmoved = set()
        for e in events:
            ev = e.get("event")
            if ev == "reclaimed":
                reclaims["stale" if "no sign of life" in e.get("reason", "") else "dead"] += 1
            elif ev == "stale_temp_removed":
                swept += int(e.get("count", 0))
            elif ev == "text" and "cannot move to" in e["line"]:
                unmoved.add(claimed_name(e["line"].split(": cannot move to")[0].rsplit("/", 1)[-1]))
            elif ev == "finished":
                if e.get("file") in unmoved:
                    unmoved.discard(e.get("file"))
                    stale_finishes += 1
                else:
                    moves[e.get("file")] += 1
    for name, k in moves.items():
        if k > 1:  # a second move to the same name would have replaced the first copy
            duplicated.add(name)
            violations.add("%s was moved out of running/ %d times (worker logs)" % (name, k))
    figures["reclaims_dead_worker"] = reclaims["dead"]
    figures["reclaims_no_sign_of_life"] = reclaims["stale"]
    figures["stale_finishes"] = stale_finishes
    figures["temp_files_swept"] = swept

    # Outputs, manifests, temp files.
    mismatched = missing = bad_manifests = 0
    for rel, ref in sorted(expected.items()):
        p = os.path.join(tmp, rel)
        if not os.path.isfile(p):
            missing += 1
            violations.add("output %s is missing" % rel)
        elif digest(p, tmp) != ref:
            mismatched += 1
            violations.add("output %s differs from the reference run" % rel)
    wanted = set(expected)
    for name in names:
        for job in jobs_of[name]:
            if not job["valid"]:
                continue
            outs = dict(job["outputs"])
            first = next(outs[k] for k in MANIFEST_KIND[job["type"]] if k in outs)
            mp = os.path.join(tmp, first + ".manifest.json")
            wanted.add(first + ".manifest.json")
            try:
                with open(mp) as f:
                    manifest = json.load(f)
                for o in manifest["outputs"]:
                    if os.path.getsize(o["path"]) != o["bytes"]:
                        raise ValueError("%s: %d bytes, the manifest says %d" % (o["path"], os.path.getsize(o["path"]), o["bytes"]))
            except (OSError, ValueError, KeyError) as e:
                bad_manifests += 1
                violations.add("%s: job %s: manifest %s: %s" % (name, job["id"], first + ".manifest.json", e))
    temp_left = []
    for top in ("out", "spool"):
        for dirpath, dirnames, filenames in os.walk(os.path.join(tmp, top)):
            for n in dirnames + filenames:
                rel = os.path.relpath(os.path.join(dirpath, n), tmp)
                if TEMP_MARKER in n:
                    temp_left.append(rel)
                elif top == "out" and n in filenames and rel not in wanted:
                    violations.add("%s: a file no job writes" % rel)
    for rel in temp_left:
        violations.add("temp or staging file left: %s" % rel)

    # Every job of done/ is up to date: a dry run of those files (their relative paths resolve
    # against done/, a sibling of pending/) would run nothing.
    in_done = [os.path.join(spool, p) for places in where.values() for p in places if p.startswith("done/")]
    stale_jobs = 0
    if in_done:
        try:
            dry = subprocess.run([args.prtbake, "run", "--dry-run", "--log-json", "--quiet"] + in_done,
                                 stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=max(1.0, left()))
        except subprocess.TimeoutExpired:
            raise DeadlineExceeded("in the final dry run")
        for e in parse_events(dry.stderr):
            if e.get("event") == "job_end" and e.get("status") != "skipped":
                stale_jobs += 1
                violations.add("job %s of %s is not up to date after the queue: %s"
                               % (e.get("id"), os.path.basename(e.get("file", "?")), e.get("reason", e.get("status"))))
        if dry.returncode != 0 and not stale_jobs:
            violations.add("the final dry run exited with %d: %s" % (dry.returncode, dry.stderr.strip()[-1000:]))
    figures.update([("lost", lost), ("duplicated", len(duplicated)), ("wrong_place", wrong),
                    ("mismatched", mismatched), ("missing_outputs", missing), ("bad_manifests", bad_manifests),
                    ("temp_files_left", len(temp_left)), ("not_up_to_date", stale_jobs)])


if __name__ == "__main__":
    sys.exit(main())
