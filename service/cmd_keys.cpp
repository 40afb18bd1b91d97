// prtbake keys: every job type's keys as Markdown tables, from the one declaration that the job
// validator and the command line also read (options.h). docs/jobs.md holds this output; a test
// checks that it still does.
#include <iostream>

#include "cli.h"
#include "jobs.h"
#include "prtbake/error.h"

namespace prtbake::cli {
namespace {

int runKeys(const CommandLine& cl) {
  bool found = false;
  for (const auto& t : jobs::jobTypes()) {
    if (!cl.positional.empty() && cl.positional[0] != t.name) continue;
    found = true;
    std::cout << "#### `" << t.name << "`\n\n| key | option | values | meaning |\n|---|---|---|---|\n";
    for (const auto& k : t.keys) {
      const std::string range = jobs::describeRange(k);
      std::cout << "| `" << k.name << "` | " << (k.onCommandLine ? "`" + k.cliName() + "`" : "(jobs only)") << " | "
                << (range.empty() ? (k.kind == jobs::ValueKind::Boolean ? "true or false, default false" : "a path")
                                  : range)
                << " | " << k.help << " |\n";
    }
    std::cout << "\n";
  }
  if (!found) throw UsageError("keys", "unknown job type '" + cl.positional[0] + "'");
  return 0;
}

PRTBAKE_COMMAND(Command{"keys", "every job type's keys and their command-line options (Markdown, as in docs/jobs.md)",
                        "prtbake keys [TYPE]\nPrints the keys of every job type, or of TYPE: name, command-line "
                        "option, values with the default, meaning.",
                        {}, 0, 1, runKeys});

}  // namespace
}  // namespace prtbake::cli
