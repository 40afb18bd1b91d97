// prtbake run: run the jobs of one or more job files (docs/jobs.md).
#include <sstream>

#include "cli.h"
#include "confine.h"
#include "prtbake/error.h"
#include "progress.h"
#include "runner.h"

namespace prtbake::cli {
namespace {

std::set<std::string> parseIdList(const std::string& text) {
  std::set<std::string> ids;
  std::stringstream ss(text);
  std::string id;
  while (std::getline(ss, id, ','))
    if (!id.empty()) ids.insert(id);
  if (ids.empty()) throw UsageError("--jobs", "expected a comma-separated list of job ids");
  return ids;
}

int runRun(const CommandLine& cl) {
  jobs::RunOptions options;
  options.force = cl.has("force");
  options.dryRun = cl.has("dry-run");
  options.device = cl.device();
  options.progress = jobs::Progress::wanted(cl.quiet(), cl.has("progress"));
  if (cl.has("jobs")) options.only = parseIdList(cl.get("jobs"));
  if (cl.has("shard")) {
    options.shard = jobs::parseShardSpec(cl.get("shard"));
    // Job k belongs to shard k mod N over the whole file: a subset would renumber it.
    if (cl.has("jobs")) throw UsageError("--shard", "cannot be combined with --jobs");
  }
  if (cl.has("input-root") || cl.has("output-root"))
    options.confinement = std::make_shared<jobs::Confinement>(jobs::splitRootList(cl.get("input-root")),
                                                              jobs::splitRootList(cl.get("output-root")));
  jobs::Reporter reporter(cl.quiet(), cl.has("log-json"));
  jobs::Runner runner(options, reporter);
  std::vector<jobs::JobFileRef> files;
  for (const auto& p : cl.positional) files.push_back({p, p, ""});
  const jobs::RunTotals totals = runner.run(files);
  runner.printSummary(totals);
  return totals.allSucceeded() ? 0 : 1;
}

PRTBAKE_COMMAND(Command{
    "run", "run the jobs of job files (skips jobs whose outputs are up to date)",
    "prtbake run JOBFILE... [--force] [--jobs ID,...] [--dry-run] [--shard I/N]\n\n"
    "Validates every job file first and reports every problem; runs the valid jobs on one\n"
    "OpenCL runtime (started only if some job has work to do); each job's outputs appear\n"
    "together or not at all, followed by <first output>.manifest.json. Exit code 0 when\n"
    "every job succeeded or was up to date, 1 otherwise, 2 for usage errors. See docs/jobs.md.\n"
    "With --shard I/N only shard I's part runs: job k of the file when k mod N = I, and its\n"
    "vertex range of every transport job with \"split\": true (then: prtbake merge; see\n"
    "docs/scaleout.md). With --input-root/--output-root, jobs read and write only below those\n"
    "directories, through no symbolic link (docs/jobs.md, \"A shared queue\").",
    {{"force", false, "rerun jobs even when their manifest shows them up to date"},
     {"jobs", true, "run only the jobs with these ids (comma-separated)"},
     {"dry-run", false, "validate and print what would run, without running anything"},
     {"shard", true, "I/N or auto/N: run shard I of N (auto: $SLURM_ARRAY_TASK_ID or $JOB_COMPLETION_INDEX)"},
     {"input-root", true, "read inputs only below these directories (DIR[:DIR...]), following no link"},
     {"output-root", true, "write outputs only below these directories (DIR[:DIR...]), following no link"}},
    1, 1000000, runRun});

}  // namespace
}  // namespace prtbake::cli
