// The batch runner behind `prtbake run` and `prtbake queue`: validates job
// files, skips up-to-date jobs, runs the others on one lazily created OpenCL
// runtime, commits each job's outputs as a set and writes its manifest last.
#pragma once

#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "jobs.h"
#include "shard.h"

namespace prtbake::jobs {

class Progress;
class OutputDirs;

// Where status lines, errors and JSON events go. Status lines ("[ok] id (1.23 s)")
// go to stdout unless quiet; errors ("prtbake: error: ...") to stderr always;
// events (one JSON object per line) to stderr with --log-json. A capture, when
// set, receives the status and error lines too (the queue's per-file log).
class Reporter {
 public:
  Reporter(bool quiet, bool logJson) : quiet_(quiet), logJson_(logJson) {}
  void status(const std::string& line);
  void error(const std::string& line);  // without the "prtbake: error: " prefix
  void event(json e);
  void setCapture(std::ostringstream* capture) { capture_ = capture; }
  // A progress line on the terminal is cleared before each status or error line.
  void setProgress(Progress* progress) { progress_ = progress; }
  bool quiet() const { return quiet_; }

 private:
  bool quiet_, logJson_;
  std::ostringstream* capture_ = nullptr;
  Progress* progress_ = nullptr;
};

struct RunOptions {
  bool force = false;             // rerun up-to-date jobs
  bool dryRun = false;            // validate and say what would run; run nothing
  std::set<std::string> only;     // --jobs: run only these ids (empty: all)
  std::string device;             // --device spec for the runtime
  bool progress = false;          // "[3/20] id ... ETA" on stderr (see progress.h)
  ShardSpec shard;                // --shard I/N: run only shard I's part (shard.h)
  JobFileLimits limits;           // a job file's size and job count (its confinement: below)
  std::shared_ptr<const Confinement> confinement;  // roots for inputs and outputs (confine.h; none: anywhere)
};

struct JobFileRef {
  std::string path;     // the file to read
  std::string display;  // its name in messages (default: path)
  std::string baseDir;  // where relative paths resolve (default: the file's directory)
};

struct RunTotals {
  int ok = 0, skipped = 0, failed = 0;
  int badFiles = 0;  // job files that could not be read or parsed at all
  double seconds = 0;
  bool allSucceeded() const { return failed == 0 && badFiles == 0; }
};

class Runner {
 public:
  Runner(RunOptions options, Reporter& reporter);
  ~Runner();

  // Validates every file, then runs every selected job; prints a status line per
  // job. Throws UsageError when --jobs names an id that no file has.
  RunTotals run(const std::vector<JobFileRef>& files);
  void printSummary(const RunTotals& totals);

  bool runtimeStarted() const { return runtime_ != nullptr; }

 private:
  void runJob(const Job& job, RunTotals& totals);
  // Removes the temp and staging files of killed runs in the directories a job writes to.
  void sweepTempFiles(const std::set<std::string>& dirs);
  // Runs a valid job into staged outputs and commits them with their manifest (throws on
  // failure, leaving the previous outputs' manifest gone and no new output in place).
  void execute(const Job& job, OutputDirs& dirs, std::chrono::steady_clock::time_point t0);
  Runtime& runtime();

  RunOptions options_;
  Reporter& reporter_;
  Runtime* runtime_ = nullptr;  // processRuntime's, once a job needs it
  double runtimeStartupSeconds_ = 0;
};

}  // namespace prtbake::jobs
