// Fuzz target: job files (`prtbake run`, and the queue's spool entries, which are job
// files) through loadJobFile and checkOutputConflicts, then every valid job's manifest
// through whyOutOfDate, as an incremental rerun reads it.
// Input: two parts (fuzz_target.h's splitParts): the job file, written as job.json
// beside an input file in.exr; and the manifest, written as out.json.manifest.json,
// which is the manifest of a job whose first output is "out.json".
// The file is loaded a second time confined, as a shared queue loads it (confine.h): roots
// in/ and out/ below the scratch directory, a link in each, small limits; every job accepted
// then reads and writes only below its roots.
#include <unistd.h>

#include <filesystem>

#include "confine.h"
#include "fuzz_target.h"
#include "jobs.h"
#include "manifest.h"

using namespace prtbake;

PRTBAKE_FUZZ_TARGET(jobfile) {
  fuzz::clearScratch();
  const std::vector<std::string> parts = fuzz::splitParts(data, size, 2);
  fuzz::writeScratch("in.exr", "not read: job files are validated without reading inputs");
  fuzz::writeScratch("out.json", "{}");
  fuzz::writeScratch("out.json.manifest.json", parts[1]);
  const std::string path = fuzz::writeScratch("job.json", parts[0]);
  std::vector<jobs::JobFile> files;
  if (!fuzz::expectCleanFailure(path, [&] { files.push_back(jobs::loadJobFile(path)); })) fuzz::fail("loadJobFile threw");
  jobs::checkOutputConflicts(files);
  for (const auto& p : files[0].fileProblems) {
    const std::string line = jobs::formatProblem(path, p);
    if (line.find('\n') != std::string::npos) fuzz::fail("problem spans lines: " + line);
  }
  for (const auto& job : files[0].jobs) {
    for (const auto& p : job.problems)
      if (jobs::formatProblem(path, p).find('\n') != std::string::npos) fuzz::fail("problem spans lines");
    if (!job.valid()) continue;
    if (!job.type || job.outputs.empty()) fuzz::fail("a valid job without a type or outputs");
    // Every valid job reaches the manifest check; only this one names the fuzzed manifest.
    const std::string manifest = job.manifestPath;
    fuzz::expectCleanFailure(manifest, [&] { jobs::whyOutOfDate(job); });
  }

  const std::string dir = fuzz::scratchDir();
  std::filesystem::create_directories(dir + "/in");
  std::filesystem::create_directories(dir + "/out");
  fuzz::writeScratch("in/in.exr", "not read");
  ::symlink("..", (dir + "/in/up").c_str());
  ::symlink("..", (dir + "/out/up").c_str());
  const jobs::Confinement confinement({dir + "/in"}, {dir + "/out"});
  jobs::JobFileLimits limits;
  limits.maxBytes = 4096;
  limits.maxJobs = 8;
  limits.confinement = &confinement;
  jobs::JobFile confined;
  if (!fuzz::expectCleanFailure(path, [&] { confined = jobs::loadJobFile(path, dir + "/out", limits); }))
    fuzz::fail("loadJobFile threw under confinement");
  if (confined.jobs.size() > limits.maxJobs) fuzz::fail("more jobs than the limit");
  // Under the root, with no `..` and no link that exists on the way (a missing directory
  // may be named anything, "up" included: the runner creates it).
  auto below = [](const std::string& p, const std::string& root) {
    if (p.compare(0, root.size() + 1, root + "/") != 0 || p.find("/../") != std::string::npos) return false;
    for (size_t slash = p.find('/', root.size() + 1); slash != std::string::npos; slash = p.find('/', slash + 1))
      if (std::filesystem::is_symlink(std::filesystem::symlink_status(p.substr(0, slash)))) return false;
    return true;
  };
  for (const auto& job : confined.jobs) {
    if (!job.valid()) continue;
    if (!job.input.empty() && !below(job.input, dir + "/in")) fuzz::fail("confined job reads " + job.input);
    for (const auto& o : job.outputs)
      if (!below(o.path, dir + "/out")) fuzz::fail("confined job writes " + o.path);
  }
  return 0;
}
