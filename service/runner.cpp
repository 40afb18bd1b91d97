// The batch runner (see runner.h).
#include "runner.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <iostream>

#include "confine.h"
#include "manifest.h"
#include "progress.h"
#include "prtbake/atomic_file.h"
#include "prtbake/clock.h"
#include "prtbake/error.h"
#include "prtbake/progress.h"

namespace prtbake::jobs {
namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

std::string formatSeconds(double s) {
  std::ostringstream ss;
  ss << std::fixed << std::setprecision(2) << s << " s";
  return ss.str();
}

std::string dirOf(const std::string& path) { return fs::path(path).parent_path().string(); }

void fsyncDir(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

std::string baseOf(const std::string& path) { return fs::path(path).filename().string(); }

}  // namespace

// The directories a job writes to. Under output confinement (confine.h) each is opened once
// from its root without following links (and created), and every path the runner writes,
// renames or removes there is pinned to that descriptor; otherwise paths are used as named.
class OutputDirs {
 public:
  OutputDirs(const Job& job, const Confinement* confinement) {
    for (const auto& o : job.outputs) dirs_.emplace(dirOf(o.path), nullptr);
    if (confinement && confinement->confinesOutputs())
      for (auto& [dir, pinned] : dirs_) pinned = confinement->openOutputDir(dir);
  }
  void create() const {
    for (const auto& [dir, pinned] : dirs_)
      if (!pinned) fs::create_directories(dir);
  }
  std::set<std::string> pinnedDirs() const {
    std::set<std::string> dirs;
    for (const auto& [dir, pinned] : dirs_) dirs.insert(pinned ? pinned->pinnedPath("") : dir);
    return dirs;
  }
  std::string pinned(const std::string& path) const {
    const auto it = dirs_.find(dirOf(path));
    return it == dirs_.end() || !it->second ? path : it->second->pinnedPath(baseOf(path));
  }
  // Creates the directory `name` in `dir` (one of the job's); returns a path to it, pinned to
  // its own descriptor under confinement.
  std::string makeStagingDir(const std::string& dir, const std::string& name) {
    const auto& pinned = dirs_.at(dir);
    if (pinned) {
      staging_.push_back(pinned->makeSubdir(name));
      return staging_.back()->pinnedPath("");
    }
    const std::string path = (fs::path(dir) / name).string();
    if (::mkdir(path.c_str(), 0777) != 0)
      throw OutputError(path, std::string("cannot create the directory: ") + std::strerror(errno));
    return path;
  }

 private:
  std::map<std::string, std::unique_ptr<Confinement::Dir>> dirs_;
  std::vector<std::unique_ptr<Confinement::Dir>> staging_;
};

namespace {

// The outputs of one job while it runs. The product writes each output under its own name
// in a staging directory beside it (".stage.prtbake-tmp.<pid>.<n>/<name>": hidden, and
// recognised by removeStaleTempFiles after a kill), so that a writer that records a file's
// name (a sidecar naming its image) records the final one; commit() renames them all to their
// final names. The previous version of each output stays reachable under a hidden name
// (".<name>.prtbake-tmp.<pid>.prev": a second link of a file, the moved-aside directory of
// a package), and so does the old manifest (setAside), until keep() drops them once the new
// manifest is written. Until then restore(), also run on destruction, puts the previous
// versions back and removes the new outputs that had none: a job that fails before or after
// the renames (a manifest that cannot be written: a full disk, an I/O error) leaves the
// previous version intact and no staging file behind.
class StagedOutputs {
 public:
  StagedOutputs(const Job& job, OutputDirs& dirs) {
    static int counter = 0;
    for (const auto& o : job.outputs) {
      const fs::path p(o.path);
      const std::string name = ".stage.prtbake-tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
      // Removed through its parent (a link swapped in for it is removed, not followed).
      stagingDirs_.push_back(dirs.pinned((p.parent_path() / name).string()));
      const std::string staging = dirs.makeStagingDir(p.parent_path().string(), name) + "/" + p.filename().string();
      paths_[o.kind] = staging;
      order_.push_back({staging, dirs.pinned(o.path), o.path});
    }
  }
  ~StagedOutputs() {
    std::error_code ec;
    for (const auto& d : stagingDirs_) fs::remove_all(d, ec);
    restore();
  }
  StagedOutputs(const StagedOutputs&) = delete;
  StagedOutputs& operator=(const StagedOutputs&) = delete;

  const std::map<std::string, std::string>& paths() const { return paths_; }

  // The output a product's error names by its staging path, under its own name.
  [[noreturn]] void rethrowNamed(const OutputError& e) const {
    for (const auto& o : order_)
      if (e.subject().rfind(o.staging, 0) == 0) throw OutputError(o.shown, e.detail());
    throw e;
  }

  void checkAllWritten() const {
    struct stat st {};
    for (const auto& [kind, staging] : paths_)
      if (::stat(staging.c_str(), &st) != 0)
        throw OutputError("outputs." + kind, "the product did not write this output");
  }

  // Moves the old manifest (`pinned`, named `shown`) aside: it must never vouch for a mixed set.
  void setAside(const std::string& pinned, const std::string& shown) {
    const std::string aside = asideName(pinned);
    if (::rename(pinned.c_str(), aside.c_str()) == 0) previous_.push_back({aside, pinned, false});
    else if (errno != ENOENT)
      throw OutputError(shown, std::string("cannot move the old manifest aside: ") + std::strerror(errno));
  }

  void commit() {
    std::error_code ec;
    for (const auto& [staging, final, shown] : order_) {
      // A directory output (an ibl package) replaces the previous one: that is moved aside
      // first (rename cannot replace a non-empty directory). A file stays in place, with a
      // second link, until the new one replaces it.
      const bool dir = fs::is_directory(staging, ec) && fs::is_directory(fs::symlink_status(final, ec));
      const std::string aside = asideName(final);
      fs::remove_all(aside, ec);
      if ((dir ? ::rename(final.c_str(), aside.c_str()) : ::link(final.c_str(), aside.c_str())) == 0) {
        previous_.push_back({aside, final, dir});
      } else if (errno != ENOENT && errno != EPERM && errno != EOPNOTSUPP && errno != EMLINK) {
        // ENOENT: no previous version; the others: no second link on this filesystem, so the
        // previous version is replaced without a copy kept; ENOSPC, EIO, ...: fail now.
        const std::string why = std::strerror(errno);
        restore();
        throw OutputError(shown, "cannot keep the previous version: " + why);
      }
      if (::rename(staging.c_str(), final.c_str()) != 0) {
        const std::string why = std::strerror(errno);
        restore();
        throw OutputError(shown, "rename failed: " + why);
      }
      committed_.push_back(final);
    }
    for (const auto& d : stagingDirs_) fs::remove_all(d, ec);
    stagingDirs_.clear();
    std::set<std::string> dirs;
    for (const auto& c : committed_) dirs.insert(dirOf(c));
    for (const auto& d : dirs) fsyncDir(d);
    order_.clear();  // no staging file left
  }

  // The new outputs and their manifest are in place: the previous versions go.
  void keep() {
    std::error_code ec;
    for (const auto& p : previous_) fs::remove_all(p.aside, ec);
    previous_.clear();
    committed_.clear();
  }

 private:
  struct Staged {
    std::string staging, final, shown;  // the product's path, the final path (both pinned), the name
  };
  struct Previous {
    std::string aside, final;
    bool dir;
  };

  static std::string asideName(const std::string& path) {
    const fs::path f(path);
    return (f.parent_path() / ("." + f.filename().string() + ".prtbake-tmp." + std::to_string(::getpid()) + ".prev"))
        .string();
  }

  // The previous versions back (the manifest last), the new outputs that had none removed.
  void restore() {
    std::error_code ec;
    std::set<std::string> restored;
    for (auto it = previous_.rbegin(); it != previous_.rend(); ++it) {
      if (it->dir) fs::remove_all(it->final, ec);
      ::rename(it->aside.c_str(), it->final.c_str());
      ::unlink(it->aside.c_str());  // still there when both names were links of the same file
      restored.insert(it->final);
    }
    for (const auto& c : committed_)
      if (!restored.count(c)) fs::remove_all(c, ec);
    previous_.clear();
    committed_.clear();
  }

  std::map<std::string, std::string> paths_;  // kind → staging path
  std::vector<std::string> stagingDirs_;
  std::vector<Staged> order_;
  std::vector<Previous> previous_;     // set aside, in order
  std::vector<std::string> committed_;  // outputs renamed into place
};

// Under input confinement, the job's inputs are checked again just before it runs (the
// queue may have held it a while) and every file the product read, after it ran.
void checkConfinedInputs(const Confinement* confinement, const Job& job, const std::vector<std::string>& read) {
  if (!confinement || !confinement->confinesInputs()) return;
  std::vector<std::string> paths = read;
  if (!job.input.empty()) paths.push_back(job.input);
  for (const auto& k : job.type->keys)
    if (k.kind == ValueKind::Path && job.params.contains(k.name) && job.params[k.name].is_string())
      paths.push_back(job.params[k.name].get<std::string>());
  for (const auto& p : paths)
    if (const std::string why = confinement->checkInput(p); !why.empty()) throw InputError("input", why);
}

// With --shard, processes on other hosts write to the same directories at the same time,
// and the pid in a temp file's name says nothing about a process on another host: a
// sharded run removes only temp and staging files untouched for this long (a temp file
// lives from its first write to its rename, seconds for any product).
constexpr double kShardStaleTempSeconds = 3600;

int removeOldTempFiles(const std::string& dir, double ageSeconds) {
  int removed = 0;
  std::error_code ec;
  const auto now = fs::file_time_type::clock::now();
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.empty() || name[0] != '.' || name.find(".prtbake-tmp.") == std::string::npos) continue;
    std::error_code tec;
    const auto t = fs::last_write_time(e.path(), tec);
    if (tec || std::chrono::duration<double>(now - t).count() < ageSeconds) continue;
    if (fs::remove_all(e.path(), tec) > 0 && !tec) ++removed;
  }
  return removed;
}

// The reason an exception gives, without repeating the job id.
std::string reasonOf(const Job& job, const std::exception& e) {
  if (auto* pe = dynamic_cast<const Error*>(&e); pe && pe->subject() == job.id) return pe->detail();
  return e.what();
}

}  // namespace

void Reporter::status(const std::string& line) {
  if (progress_) progress_->clearLine();
  if (capture_) *capture_ << line << "\n";
  if (!quiet_) std::cout << line << std::endl;
}

void Reporter::error(const std::string& line) {
  if (progress_) progress_->clearLine();
  if (capture_) *capture_ << "error: " << line << "\n";
  std::cerr << "prtbake: error: " << line << std::endl;
}

void Reporter::event(json e) {
  if (!logJson_) return;
  e["time"] = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  std::cerr << e.dump() << std::endl;
}

Runner::Runner(RunOptions options, Reporter& reporter) : options_(std::move(options)), reporter_(reporter) {}
Runner::~Runner() = default;

Runtime& Runner::runtime() {
  if (!runtime_) {
    const auto t0 = Clock::now();
    runtime_ = &processRuntime(options_.device);
    runtimeStartupSeconds_ = secondsSince(t0);
    reporter_.event({{"event", "runtime_start"}, {"device", runtime_->deviceLabel()},
                     {"seconds", runtimeStartupSeconds_}});
  }
  return *runtime_;
}

RunTotals Runner::run(const std::vector<JobFileRef>& refs) {
  const auto t0 = Clock::now();
  RunTotals totals;
  std::vector<JobFile> files;
  for (const auto& ref : refs) {
    JobFileLimits limits = options_.limits;
    limits.confinement = options_.confinement.get();
    JobFile f = loadJobFile(ref.path, ref.baseDir, limits);
    const std::string display = ref.display.empty() ? ref.path : ref.display;
    f.path = display;
    for (auto& job : f.jobs) job.jobFile = display;
    if (!options_.only.empty())  // --jobs: drop the others before they are judged
      f.jobs.erase(std::remove_if(f.jobs.begin(), f.jobs.end(),
                                  [&](const Job& j) { return !options_.only.count(j.id); }),
                   f.jobs.end());
    files.push_back(std::move(f));
  }
  for (const auto& id : options_.only) {
    bool found = false;
    for (const auto& f : files)
      for (const auto& j : f.jobs) found = found || j.id == id;
    bool fileProblems = false;
    for (const auto& f : files) fileProblems = fileProblems || !f.fileProblems.empty();
    if (!found && !fileProblems) throw UsageError("--jobs", "no job file has a job with id '" + id + "'");
  }
  checkOutputConflicts(files);

  // Every problem first, before anything runs: one bad job never hides another.
  for (const auto& f : files) {
    if (!f.fileProblems.empty()) ++totals.badFiles;
    for (const auto& p : f.fileProblems) {
      reporter_.error(formatProblem(f.path, p));
      reporter_.event({{"event", "error"}, {"file", f.path}, {"key", p.key}, {"message", p.what}});
    }
    for (const auto& job : f.jobs)
      for (const auto& p : job.problems) {
        reporter_.error(formatProblem(f.path, p));
        reporter_.event({{"event", "error"}, {"file", f.path}, {"job", p.job}, {"key", p.key}, {"message", p.what}});
      }
  }
  int jobCount = 0, index = 0;
  for (const auto& f : files) jobCount += int(f.jobs.size());
  Progress progress(options_.progress && !options_.dryRun, jobCount);
  reporter_.setProgress(&progress);
  const ShardSpec& shard = options_.shard;
  size_t position = 0;  // k: whole job k belongs to shard k mod N (shard.h)
  for (const auto& f : files)
    for (const auto& job : f.jobs) {
      const size_t k = position++;
      progress.begin(++index, job.label);
      const auto tJob = Clock::now();
      const int ranBefore = totals.ok + totals.failed;
      if (!shard.active()) {
        runJob(job, totals);
      } else if (isSplit(job)) {
        runJob(partialJob(job, shard), totals);
      } else if (shardOfJob(k, shard.count) == shard.index) {
        Job owned = job;
        if (!job.outputs.empty()) owned.failureMarker = failureMarkerPath(job, shard.index, shard.count);
        runJob(owned, totals);
      }
      progress.end(secondsSince(tJob), job.valid() && totals.ok + totals.failed > ranBefore);
    }
  progress.clearLine();
  reporter_.setProgress(nullptr);
  totals.seconds = secondsSince(t0);
  return totals;
}

void Runner::sweepTempFiles(const std::set<std::string>& dirs) {
  for (const auto& d : dirs)
    if (const int n = options_.shard.active() ? removeOldTempFiles(d, kShardStaleTempSeconds) : removeStaleTempFiles(d);
        n > 0)
      reporter_.event({{"event", "stale_temp_removed"}, {"dir", d}, {"count", n}});
}

void Runner::execute(const Job& job, OutputDirs& dirs, Clock::time_point t0) {
  dirs.create();
  checkConfinedInputs(options_.confinement.get(), job, {});
  StagedOutputs staged(job, dirs);
  ExecContext ctx{[this]() -> Runtime& { return runtime(); }, staged.paths()};
  const double startupBefore = runtime_ ? 0.0 : -1.0;
  const auto tRun = Clock::now();
  ExecResult result;
  try {
    result = job.type->execute(job, ctx);
  } catch (const OutputError& e) {
    staged.rethrowNamed(e);
  }
  const double runSeconds = secondsSince(tRun);
  staged.checkAllWritten();
  const std::vector<std::string> read = filesRead(job, result.inputFiles);
  checkConfinedInputs(options_.confinement.get(), job, read);
  const auto inputs = hashInputs(read, result.inputHashes);

  // Commit: the old manifest goes aside first (so it never vouches for a mixed set),
  // then the outputs as a set, then the new manifest, last. Until that is written, a
  // failure (an exception out of here) puts the previous outputs and manifest back.
  const std::string manifestPath = dirs.pinned(job.manifestPath);
  // Two workers may run one job at once (a paused worker's claim taken back, then the worker
  // resumed): their commits take turns on a lock of the manifest's directory, so that the
  // outputs and the manifest in place always come from the same run (the queue's load test
  // saw an output of one run beside the manifest of the other).
  struct CommitLock {
    int fd;
    explicit CommitLock(const std::string& dir) : fd(::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)) {
      while (fd >= 0 && ::flock(fd, LOCK_EX) != 0 && errno == EINTR) {
      }
    }
    ~CommitLock() {
      if (fd >= 0) ::close(fd);  // closing releases the lock
    }
  } commitLock(dirOf(manifestPath));
  staged.setAside(manifestPath, job.manifestPath);
  staged.commit();
  json timings = {{"run_seconds", runSeconds}, {"total_seconds", secondsSince(t0)}};
  if (startupBefore < 0 && runtime_) timings["runtime_startup_seconds"] = runtimeStartupSeconds_;
  const json manifest = makeManifest(job, inputs, runtime_ ? runtime_->deviceLabel() : "", timings, result.report);
  try {
    writeFileAtomic(manifestPath, manifest.dump(2) + "\n");
  } catch (const OutputError& e) {
    throw OutputError(job.manifestPath, e.detail());
  }
  staged.keep();
}

void Runner::runJob(const Job& job, RunTotals& totals) {
  const auto t0 = Clock::now();
  json end = {{"event", "job_end"}, {"file", job.jobFile}, {"id", job.label}};
  reporter_.event({{"event", "job_start"}, {"file", job.jobFile}, {"id", job.label},
                   {"type", job.type ? job.type->name : ""}});
  auto fail = [&](const std::string& reason) {
    ++totals.failed;
    if (!job.failureMarker.empty() && !options_.dryRun) {
      try {
        writeFileAtomic(job.failureMarker, json{{"id", job.id}, {"job_file", job.jobFile},
                                                {"parameters", job.params}, {"error", reason}}.dump(2) + "\n");
      } catch (const std::exception&) {
        // The missing partial result still keeps merge from using this shard.
      }
    }
    end["status"] = "failed";
    end["error"] = reason;
    end["seconds"] = secondsSince(t0);
    reporter_.status("[failed] " + job.label + ": " + reason);
    if (reporter_.quiet() && job.valid()) reporter_.error(job.jobFile + ": job '" + job.label + "': " + reason);
    reporter_.event(end);
  };
  if (!job.valid()) {
    const size_t n = job.problems.size();
    fail("invalid job (" + std::to_string(n) + (n == 1 ? " problem" : " problems") + ", see above)");
    return;
  }
  // Temp and staging files of killed runs, in every directory this job writes to.
  std::unique_ptr<OutputDirs> dirs;
  try {
    dirs = std::make_unique<OutputDirs>(job, options_.dryRun ? nullptr : options_.confinement.get());
  } catch (const std::exception& e) {
    fail(reasonOf(job, e));
    return;
  }
  if (!options_.dryRun) sweepTempFiles(dirs->pinnedDirs());

  if (!options_.force) {
    const std::string why = whyOutOfDate(job);
    if (why.empty()) {
      ++totals.skipped;
      if (!job.failureMarker.empty()) ::unlink(job.failureMarker.c_str());
      end["status"] = "skipped";
      end["seconds"] = secondsSince(t0);
      reporter_.status("[skipped] " + job.label + " (up to date)");
      reporter_.event(end);
      return;
    }
    end["reason"] = why;
  }
  if (options_.dryRun) {
    ++totals.ok;
    end["status"] = "would_run";
    end["parameters"] = job.params;
    end["seconds"] = secondsSince(t0);
    reporter_.status("[would run] " + job.label + " (" + (options_.force ? "--force" : end["reason"].get<std::string>()) + ")");
    reporter_.event(end);
    return;
  }

  try {
    execute(job, *dirs, t0);
  } catch (const cl::Error& e) {
    fail(describeClError(e, runtime_ ? runtime_->deviceLabel() : lastDeviceLabel()));
    return;
  } catch (const std::bad_alloc&) {
    fail("out of host memory");
    return;
  } catch (const Cancelled& e) {  // the caller stopped the run (prtbake/progress.h): no more jobs
    fail(e.what());
    throw;
  } catch (const std::exception& e) {
    fail(reasonOf(job, e));
    return;
  }
  ++totals.ok;
  if (!job.failureMarker.empty()) ::unlink(job.failureMarker.c_str());
  const double seconds = secondsSince(t0);
  end["status"] = "ok";
  end["seconds"] = seconds;
  reporter_.status("[ok] " + job.label + " (" + formatSeconds(seconds) + ")");
  reporter_.event(end);
}

void Runner::printSummary(const RunTotals& t) {
  const int total = t.ok + t.skipped + t.failed;
  reporter_.status(std::to_string(total) + (total == 1 ? " job: " : " jobs: ") + std::to_string(t.ok) + (options_.dryRun ? " to run, " : " ok, ") +
                   std::to_string(t.skipped) + " skipped, " + std::to_string(t.failed) + " failed (" +
                   formatSeconds(t.seconds) + ")" +
                   (t.badFiles ? "; " + std::to_string(t.badFiles) + " job file(s) could not be read" : ""));
  reporter_.event({{"event", "summary"}, {"ok", t.ok}, {"skipped", t.skipped}, {"failed", t.failed},
                   {"bad_files", t.badFiles},
                   {"seconds", t.seconds}, {"runtime_started", runtime_ != nullptr}});
}

}  // namespace prtbake::jobs
