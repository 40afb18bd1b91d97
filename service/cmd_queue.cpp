// prtbake queue: work through a spool directory of job files.
//
// DIR/pending  job files waiting (*.json; submit by renaming into place)
// DIR/running  claimed files, named <name>.<host>.<pid>
// DIR/done     finished files (every job ok or up to date) and their logs, <stem>.log
// DIR/failed   finished files with at least one failed job, and their logs
//
// A worker claims a file by renaming it from pending/ into running/; rename is
// atomic on one filesystem (also over NFS), so exactly one worker wins and the
// others see ENOENT and move on. A worker reads only the file it claimed. While
// it runs a file it touches the claim periodically; a claim whose pid is dead on
// this host, or whose last touch is older than --stale-after on any host, is
// renamed back into pending/ by the next worker that looks, so a killed worker
// loses nothing (its outputs are atomic and its staging files are removed by the
// next run that writes there).
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <mutex>
#include <thread>

#include "cli.h"
#include "confine.h"
#include "manifest.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "runner.h"

namespace prtbake::cli {
namespace {
namespace fs = std::filesystem;

std::atomic<bool> gStopRequested{false};

void onStopSignal(int sig) {
  gStopRequested = true;
  ::signal(sig, SIG_DFL);  // a second signal stops at once
}

std::string hostName() {
  char buf[256] = {};
  if (::gethostname(buf, sizeof buf - 1) != 0 || !buf[0]) return "localhost";
  std::string h = buf;
  for (auto& c : h)
    if (c == '/') c = '_';
  return h;
}

// Renames without replacing an existing file where the filesystem supports it.
bool renameNoReplace(const std::string& from, const std::string& to) {
#ifdef RENAME_NOREPLACE
  if (::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), RENAME_NOREPLACE) == 0) return true;
  if (errno != EINVAL && errno != ENOSYS) return false;
#endif
  struct stat st {};
  if (::stat(to.c_str(), &st) == 0) {
    errno = EEXIST;
    return false;
  }
  return ::rename(from.c_str(), to.c_str()) == 0;
}

bool processAlive(long pid) { return pid > 0 && (::kill(pid_t(pid), 0) == 0 || errno == EPERM); }

// Touches a claim from a helper thread while its job file runs.
class Heartbeat {
 public:
  Heartbeat(std::string path, double periodSeconds) : path_(std::move(path)) {
    touch();
    thread_ = std::thread([this, periodSeconds] {
      std::unique_lock<std::mutex> lock(mutex_);
      while (!cv_.wait_for(lock, std::chrono::duration<double>(periodSeconds), [this] { return stop_; })) touch();
    });
  }
  ~Heartbeat() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }

 private:
  void touch() { ::utimensat(AT_FDCWD, path_.c_str(), nullptr, 0); }
  std::string path_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::thread thread_;
};

class Worker {
 public:
  Worker(const CommandLine& cl, jobs::Reporter& reporter, jobs::Runner& runner)
      : dir_(cl.positional[0]), host_(hostName()), pid_(::getpid()), reporter_(reporter), runner_(runner) {
    staleAfterSeconds_ = cl.getDouble("stale-after", 600.0, 1.0, 1e7);
    pollSeconds_ = cl.getDouble("poll", 5.0, 0.01, 86400.0);
    struct stat st {};
    if (::stat(dir_.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) throw InputError(dir_, "not a directory");
    for (const char* sub : {"pending", "running", "done", "failed"}) fs::create_directories(dir_ + "/" + sub);
  }

  int run(bool drain) {
    while (!gStopRequested) {
      reclaimStaleClaims();
      if (claimNext()) continue;
      if (drain) break;
      const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(pollSeconds_);
      while (!gStopRequested && std::chrono::steady_clock::now() < until)
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    reporter_.status("queue: " + std::to_string(done_) + " job file(s) done, " + std::to_string(failed_) + " failed");
    return failed_ == 0 ? 0 : 1;
  }

 private:
  std::string sub(const std::string& name, const std::string& file) const { return dir_ + "/" + name + "/" + file; }

  std::vector<std::string> list(const std::string& name) const {
    std::vector<std::string> files;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir_ + "/" + name, ec)) files.push_back(e.path().filename().string());
    std::sort(files.begin(), files.end());
    return files;
  }

  // Claims and runs the first pending job file another worker has not taken.
  bool claimNext() {
    for (const auto& name : list("pending")) {
      if (gStopRequested) return false;
      if (name.empty() || name[0] == '.' || name.size() <= 5 || name.compare(name.size() - 5, 5, ".json") != 0)
        continue;
      const std::string claim = sub("running", name + "." + host_ + "." + std::to_string(pid_));
      if (::rename(sub("pending", name).c_str(), claim.c_str()) != 0) continue;  // taken by another worker
      runClaimed(name, claim);
      return true;
    }
    return false;
  }

  void runClaimed(const std::string& name, const std::string& claim) {
    std::ostringstream log;
    jobs::RunTotals totals;
    {
      Heartbeat heartbeat(claim, std::clamp(staleAfterSeconds_ / 4.0, 0.5, 60.0));
      reporter_.setCapture(&log);
      reporter_.status("[claimed] " + name + " (worker " + host_ + ":" + std::to_string(pid_) + ", " + jobs::utcNow() + ")");
      reporter_.event({{"event", "claimed"}, {"file", name}, {"host", host_}, {"pid", pid_}});
      try {
        totals = runner_.run({{claim, name, dir_ + "/pending"}});
      } catch (const std::exception& e) {
        reporter_.error(name + ": " + e.what());
        totals.badFiles = 1;
      }
      runner_.printSummary(totals);
      reporter_.setCapture(nullptr);
    }
    const bool ok = totals.allSucceeded();
    const std::string dest = ok ? "done" : "failed";
    const std::string stem = name.substr(0, name.size() - 5);
    appendLog(sub(dest, stem + ".log"), log.str() + "finished " + jobs::utcNow() + ": " + dest + "\n\n");
    if (::rename(claim.c_str(), sub(dest, name).c_str()) != 0) {
      reporter_.error(claim + ": cannot move to " + dest + "/: " + std::strerror(errno) +
                      " (was the claim reclaimed? raise --stale-after)");
    }
    reporter_.event({{"event", "finished"}, {"file", name}, {"status", dest}});
    (ok ? done_ : failed_)++;
  }

  // One write with O_APPEND: the log of a file that ran twice would show both runs.
  void appendLog(const std::string& path, const std::string& text) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (fd < 0) {
      reporter_.error(path + ": cannot write the log: " + std::strerror(errno));
      return;
    }
    if (::write(fd, text.data(), text.size()) != ssize_t(text.size()))
      reporter_.error(path + ": cannot write the log: " + std::strerror(errno));
    ::fsync(fd);
    ::close(fd);
  }

  // Claims are "<name>.json.<host>.<pid>"; stale ones go back to pending/.
  void reclaimStaleClaims() {
    const auto now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
    for (const auto& claimName : list("running")) {
      const auto at = claimName.rfind(".json.");
      const auto dot = claimName.rfind('.');
      if (at == std::string::npos || dot <= at + 5) continue;
      const std::string name = claimName.substr(0, at + 5);
      const std::string host = claimName.substr(at + 6, dot - at - 6);
      const long pid = std::strtol(claimName.c_str() + dot + 1, nullptr, 10);
      struct stat st {};
      if (::stat(sub("running", claimName).c_str(), &st) != 0) continue;
      // rename and touch both set ctime, so it is the time of the last sign of life.
      const double idle = std::difftime(now, std::max(st.st_mtime, st.st_ctime));
      std::string why;
      if (host == host_ && pid != pid_ && !processAlive(pid)) why = "worker process is gone";
      else if (idle > staleAfterSeconds_ && !(host == host_ && pid == pid_))
        why = "no sign of life for " + std::to_string(long(idle)) + " s";
      if (why.empty()) continue;
      std::string target = sub("pending", name);
      if (!renameNoReplace(sub("running", claimName), target)) {
        if (errno != EEXIST) continue;  // another worker reclaimed it first
        target = sub("pending", name.substr(0, name.size() - 5) + ".reclaimed-" + std::to_string(pid) + ".json");
        if (!renameNoReplace(sub("running", claimName), target)) continue;
      }
      reporter_.status("[reclaimed] " + claimName + " (" + why + ")");
      reporter_.event({{"event", "reclaimed"}, {"claim", claimName}, {"reason", why}});
    }
  }

  std::string dir_, host_;
  long pid_;
  double staleAfterSeconds_ = 600, pollSeconds_ = 5;
  jobs::Reporter& reporter_;
  jobs::Runner& runner_;
  int done_ = 0, failed_ = 0;
};

// DIR/queue.json, the queue's own settings: {"input_roots": [...], "output_roots": [...],
// "max_job_file_bytes": N, "max_jobs": N}, relative roots against DIR. Whoever can write it
// can widen the roots, so it is refused unless it is a regular file owned by DIR's owner and
// neither it nor DIR is writable by group or others.
void readQueueConfig(const std::string& dir, std::vector<std::string>* inputRoots,
                     std::vector<std::string>* outputRoots, jobs::JobFileLimits* limits) {
  const std::string path = dir + "/queue.json";
  struct stat st {}, dirSt {};
  if (::lstat(path.c_str(), &st) != 0) return;
  if (::stat(dir.c_str(), &dirSt) != 0) throw InputError(dir, std::strerror(errno));
  if (!S_ISREG(st.st_mode)) throw InputError(path, "not a regular file (a link is not followed)");
  if (st.st_uid != dirSt.st_uid)
    throw InputError(path, "owned by uid " + std::to_string(st.st_uid) + ", not by the queue directory's owner (uid " +
                               std::to_string(dirSt.st_uid) + ")");
  if (st.st_mode & (S_IWGRP | S_IWOTH)) throw InputError(path, "writable by group or others (chmod go-w)");
  if (dirSt.st_mode & (S_IWGRP | S_IWOTH))
    throw InputError(dir, "writable by group or others, so anyone could replace queue.json (chmod go-w; only pending/ needs to be shared)");
  jobs::json config;
  try {
    config = jobs::json::parse(readFile(path));
  } catch (const jobs::json::exception& e) {
    throw InputError(path, e.what());
  }
  if (!config.is_object()) throw InputError(path, "expected an object");
  auto roots = [&](const char* key, std::vector<std::string>* out) {
    if (!config.contains(key)) return;
    if (!config[key].is_array()) throw InputError(path, std::string(key) + ": expected an array of directories");
    for (const auto& r : config[key]) {
      if (!r.is_string() || r.get<std::string>().empty()) throw InputError(path, std::string(key) + ": expected a directory");
      out->push_back((fs::path(dir) / r.get<std::string>()).string());
    }
  };
  auto count = [&](const char* key, size_t* out) {
    if (!config.contains(key)) return;
    if (!config[key].is_number_unsigned() || config[key].get<uint64_t>() == 0)
      throw InputError(path, std::string(key) + ": expected a positive integer");
    *out = size_t(config[key].get<uint64_t>());
  };
  for (auto it = config.begin(); it != config.end(); ++it)
    if (it.key() != "input_roots" && it.key() != "output_roots" && it.key() != "max_job_file_bytes" && it.key() != "max_jobs")
      throw InputError(path, it.key() + ": unknown key (expected input_roots, output_roots, max_job_file_bytes, max_jobs)");
  roots("input_roots", inputRoots);
  roots("output_roots", outputRoots);
  count("max_job_file_bytes", &limits->maxBytes);
  count("max_jobs", &limits->maxJobs);
}

int runQueue(const CommandLine& cl) {
  jobs::RunOptions options;
  options.force = cl.has("force");
  options.device = cl.device();
  std::vector<std::string> inputRoots = jobs::splitRootList(cl.get("input-root")),
                           outputRoots = jobs::splitRootList(cl.get("output-root"));
  readQueueConfig(cl.positional[0], &inputRoots, &outputRoots, &options.limits);
  if (!inputRoots.empty() || !outputRoots.empty())
    options.confinement = std::make_shared<jobs::Confinement>(inputRoots, outputRoots);
  jobs::Reporter reporter(cl.quiet(), cl.has("log-json"));
  jobs::Runner runner(options, reporter);  // one runtime for every file this worker runs
  Worker worker(cl, reporter, runner);
  ::signal(SIGINT, onStopSignal);
  ::signal(SIGTERM, onStopSignal);
  return worker.run(cl.has("drain"));
}

PRTBAKE_COMMAND(Command{
    "queue", "work through a spool directory of job files (several workers may share it)",
    "prtbake queue DIR [--drain] [--poll SECONDS] [--stale-after SECONDS] [--force]\n\n"
    "Takes job files (*.json) from DIR/pending, claims each by renaming it into DIR/running,\n"
    "runs it like 'prtbake run' and moves it to DIR/done or DIR/failed with its log\n"
    "(<stem>.log beside it). Relative paths in a job file resolve against DIR/pending.\n"
    "SIGINT/SIGTERM finish the current job file, then stop. With --input-root/--output-root\n"
    "(or DIR/queue.json), jobs read and write only below those directories, through no\n"
    "symbolic link: see docs/jobs.md, \"A shared queue\".",
    {{"drain", false, "exit when nothing is pending (default: keep polling)"},
     {"poll", true, "seconds between looks at DIR/pending when idle (default 5)"},
     {"stale-after", true, "seconds after which a claim that shows no sign of life is taken back (default 600)"},
     {"force", false, "rerun jobs even when their manifest shows them up to date"},
     {"input-root", true, "read inputs only below these directories (DIR[:DIR...]), following no link"},
     {"output-root", true, "write outputs only below these directories (DIR[:DIR...]), following no link"}},
    1, 1, runQueue});

}  // namespace
}  // namespace prtbake::cli
