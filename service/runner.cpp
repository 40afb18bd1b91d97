// The batch runner (see runner.h).
#include "runner.h"

#include <fcntl.h>
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

// The outputs of one job while it runs. The product writes each output to a
// staging name in the output's directory (".stage.prtbake-tmp.<pid>.<n>.<kind><ext>":
// hidden, short, with the output's extension for writers that look at it, and
// recognised by removeStaleTempFiles after a kill);
// commit() renames them all to their final names, or removes every one of them
// (and any already renamed) when a rename fails. Uncommitted staging files are
// removed on destruction, so a failed job leaves nothing behind.
class StagedOutputs {
 public:
  explicit StagedOutputs(const Job& job) {
    static int counter = 0;
    for (const auto& o : job.outputs) {
      const fs::path p(o.path);
      const std::string staging =
          (p.parent_path() / (".stage.prtbake-tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++) +
                              "." + o.kind + p.extension().string()))
              .string();
      paths_[o.kind] = staging;
      order_.push_back({staging, o.path});
    }
  }
  ~StagedOutputs() {
    std::error_code ec;
    for (const auto& [staging, final] : order_) fs::remove_all(staging, ec);
  }
  StagedOutputs(const StagedOutputs&) = delete;
  StagedOutputs& operator=(const StagedOutputs&) = delete;

  const std::map<std::string, std::string>& paths() const { return paths_; }

  void checkAllWritten() const {
    struct stat st {};
    for (const auto& [kind, staging] : paths_)
      if (::stat(staging.c_str(), &st) != 0)
        throw OutputError("outputs." + kind, "the product did not write this output");
  }

  void commit() {
    std::vector<std::string> committed;
    std::error_code ec;
    for (const auto& [staging, final] : order_) {
      // A directory output (an ibl package) replaces the previous one: that is moved aside
      // first (rename cannot replace a non-empty directory) and removed after.
      std::string aside;
      if (fs::is_directory(staging, ec) && fs::is_directory(final, ec)) {
        const fs::path f(final);
        aside = (f.parent_path() / ("." + f.filename().string() + ".prtbake-tmp." + std::to_string(::getpid()) + ".old"))
                    .string();
        fs::remove_all(aside, ec);
        if (::rename(final.c_str(), aside.c_str()) != 0) aside.clear();
      }
      if (::rename(staging.c_str(), final.c_str()) != 0) {
        const std::string why = std::strerror(errno);
        if (!aside.empty()) ::rename(aside.c_str(), final.c_str());
        for (const auto& c : committed) fs::remove_all(c, ec);
        throw OutputError(final, "rename failed: " + why);
      }
      if (!aside.empty()) fs::remove_all(aside, ec);
      committed.push_back(final);
    }
    std::set<std::string> dirs;
    for (const auto& c : committed) dirs.insert(dirOf(c));
    for (const auto& d : dirs) fsyncDir(d);
    order_.clear();  // nothing left to clean up
  }

 private:
  std::map<std::string, std::string> paths_;                 // kind → staging path
  std::vector<std::pair<std::string, std::string>> order_;   // staging, final
};

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
    JobFile f = loadJobFile(ref.path, ref.baseDir);
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

void Runner::execute(const Job& job, const std::set<std::string>& dirs, Clock::time_point t0) {
  for (const auto& d : dirs) fs::create_directories(d);
  StagedOutputs staged(job);
  ExecContext ctx{[this]() -> Runtime& { return runtime(); }, staged.paths()};
  const double startupBefore = runtime_ ? 0.0 : -1.0;
  const auto tRun = Clock::now();
  const ExecResult result = job.type->execute(job, ctx);
  const double runSeconds = secondsSince(tRun);
  staged.checkAllWritten();
  const auto inputs = hashInputs(filesRead(job, result.inputFiles), result.inputHashes);

  // Commit: the old manifest goes first (so it never vouches for a mixed set),
  // then the outputs as a set, then the new manifest, last.
  if (::unlink(job.manifestPath.c_str()) != 0 && errno != ENOENT)
    throw OutputError(job.manifestPath, std::string("cannot remove the old manifest: ") + std::strerror(errno));
  staged.commit();
  json timings = {{"run_seconds", runSeconds}, {"total_seconds", secondsSince(t0)}};
  if (startupBefore < 0 && runtime_) timings["runtime_startup_seconds"] = runtimeStartupSeconds_;
  const json manifest = makeManifest(job, inputs, runtime_ ? runtime_->deviceLabel() : "", timings, result.report);
  try {
    writeFileAtomic(job.manifestPath, manifest.dump(2) + "\n");
  } catch (...) {
    for (const auto& o : job.outputs) ::unlink(o.path.c_str());
    throw;
  }
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
  std::set<std::string> dirs;
  for (const auto& o : job.outputs) dirs.insert(dirOf(o.path));
  if (!options_.dryRun) sweepTempFiles(dirs);

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
    execute(job, dirs, t0);
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
