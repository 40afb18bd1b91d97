// prtbake submit slurm: run a job file as a Slurm array job of N shards plus a merge
// job that starts when every array task has succeeded (docs/scaleout.md).
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <iostream>

#include "cli.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"

namespace prtbake::cli {
namespace {
namespace fs = std::filesystem;

// Single-quoted for bash.
std::string shq(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// Option values pasted into #SBATCH lines: no spaces, quotes or newlines.
std::string sbatchValue(const CommandLine& cl, const std::string& name) {
  const std::string v = cl.get(name);
  for (char c : v)
    if (std::isspace(static_cast<unsigned char>(c)) || c == '\'' || c == '"' || c == '\\')
      throw UsageError("--" + name, "'" + v + "' contains a space or a quote");
  return v;
}

std::string selfPath() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("prtbake") : p.string();
}

// Runs `command`, returns its stdout; throws naming the command when it fails.
std::string capture(const std::string& command) {
  FILE* p = ::popen((command + " 2>&1").c_str(), "r");
  if (!p) throw Error("sbatch", "cannot run: " + command);
  std::string out;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  const int st = ::pclose(p);
  if (st != 0) throw Error("sbatch", "'" + command + "' failed: " + out);
  return out;
}

// The job id in `sbatch --parsable` output: "<id>" or "<id>;<cluster>".
std::string parseJobId(const std::string& out) {
  std::string id;
  for (char c : out) {
    if (c >= '0' && c <= '9') id += c;
    else if (!id.empty()) break;
  }
  if (id.empty()) throw Error("sbatch", "no job id in its output: " + out);
  return id;
}

int runSubmit(const CommandLine& cl) {
  if (cl.positional[0] != "slurm")
    throw UsageError("submit", "unknown scheduler '" + cl.positional[0] + "' (expected slurm)");
  if (!cl.has("tasks")) throw UsageError("submit", "missing --tasks N");
  const long n = cl.getInt("tasks", 0, 1, 100000);
  const fs::path jobFile = fs::absolute(cl.positional[1]).lexically_normal();
  inputFileSize(jobFile.string());  // missing, a directory, a pipe: one error naming it
  const std::string stem = jobFile.stem().string();
  const fs::path dir = cl.has("script-dir") ? fs::absolute(cl.get("script-dir")).lexically_normal()
                                            : jobFile.parent_path() / (".prtbake-slurm-" + stem);
  std::string common;
  if (cl.has("partition")) common += "#SBATCH --partition=" + sbatchValue(cl, "partition") + "\n";
  if (cl.has("time")) common += "#SBATCH --time=" + sbatchValue(cl, "time") + "\n";
  std::string extra;
  if (cl.has("device")) extra += " --device " + shq(cl.device());
  const std::string exe = shq(cl.get("prtbake", selfPath()));
  const std::string count = std::to_string(n);

  const std::string array =
      "#!/bin/bash\n"
      "#SBATCH --job-name=prtbake-" + stem + "\n"
      "#SBATCH --array=0-" + std::to_string(n - 1) + "\n"
      "#SBATCH --ntasks=1\n"
      "#SBATCH --requeue\n"
      "#SBATCH --output=" + (dir / "logs" / "shard-%a.out").string() + "\n" + common +
      "# Shard $SLURM_ARRAY_TASK_ID of " + count + " (docs/scaleout.md). A rerun (requeue)\n"
      "# writes the same partial result, atomically, or skips it when it is complete.\n"
      "exec " + exe + " run " + shq(jobFile.string()) + " --shard \"$SLURM_ARRAY_TASK_ID/" + count + "\"" + extra + "\n";
  const std::string merge =
      "#!/bin/bash\n"
      "#SBATCH --job-name=prtbake-" + stem + "-merge\n"
      "#SBATCH --ntasks=1\n"
      "#SBATCH --output=" + (dir / "logs" / "merge.out").string() + "\n" + common +
      "# Submitted with --dependency=afterok:<array job id>: runs once every shard has succeeded.\n"
      "exec " + exe + " merge " + shq(jobFile.string()) + " --shards " + count + "\n";
  const std::string arrayPath = (dir / "array.sbatch").string(), mergePath = (dir / "merge.sbatch").string();
  const std::string sbatch = cl.get("sbatch", "sbatch");

  if (cl.has("dry-run")) {
    std::cout << "# " << arrayPath << "\n" << array << "\n# " << mergePath << "\n" << merge << "\n"
              << "# submit with:\n"
              << "#   " << sbatch << " --parsable " << arrayPath << "   -> ARRAY_ID\n"
              << "#   " << sbatch << " --parsable --dependency=afterok:ARRAY_ID " << mergePath << "\n";
    return 0;
  }
  fs::create_directories(dir / "logs");
  writeFileAtomic(arrayPath, array);
  writeFileAtomic(mergePath, merge);
  const std::string arrayId = parseJobId(capture(shq(sbatch) + " --parsable " + shq(arrayPath)));
  const std::string mergeId =
      parseJobId(capture(shq(sbatch) + " --parsable --dependency=afterok:" + arrayId + " " + shq(mergePath)));
  status(cl, "submitted array job " + arrayId + " (" + count + " tasks) and merge job " + mergeId);
  std::cout << arrayId << " " << mergeId << "\n";
  return 0;
}

PRTBAKE_COMMAND(Command{
    "submit", "run a job file as a Slurm array job of N shards plus a merge job",
    "prtbake submit slurm JOBFILE --tasks N [--partition P] [--time T] [--dry-run]\n\n"
    "Writes array.sbatch (--array=0-(N-1): prtbake run JOBFILE --shard $SLURM_ARRAY_TASK_ID/N)\n"
    "and merge.sbatch (prtbake merge JOBFILE --shards N) to --script-dir (default:\n"
    ".prtbake-slurm-<job file stem> next to the job file), submits the array with\n"
    "sbatch --parsable and the merge with --dependency=afterok:<array job id>, and prints\n"
    "both job ids. --dry-run prints the scripts and submits nothing. See docs/scaleout.md.",
    {{"tasks", true, "the number of array tasks (shards) N"},
     {"partition", true, "Slurm partition for both jobs"},
     {"time", true, "Slurm time limit for each task and the merge (e.g. 01:00:00)"},
     {"script-dir", true, "where to write the scripts and logs/"},
     {"sbatch", true, "the sbatch command (default: sbatch from PATH)"},
     {"prtbake", true, "the prtbake executable the tasks run (default: this one)"},
     {"dry-run", false, "print the scripts and the sbatch commands; submit nothing"}},
    2, 2, runSubmit});

}  // namespace
}  // namespace prtbake::cli
