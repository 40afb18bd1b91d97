// The prtbake command line: a table of subcommands, each in its own file,
// registered statically (PRTBAKE_COMMAND). Parsing is strict: an unknown option,
// a missing value or a malformed number is a usage error (exit code 2).
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace prtbake::cli {

struct OptionSpec {
  std::string name;  // without the leading "--"
  bool takesValue;
  std::string help;
};

struct CommandLine {
  std::string command;
  std::vector<std::string> positional;
  std::map<std::string, std::string> options;  // flags map to ""

  bool has(const std::string& name) const { return options.count(name) != 0; }
  std::string get(const std::string& name, const std::string& fallback = "") const;
  // Numbers must parse whole and lie in [lo, hi]; otherwise a UsageError names the option.
  long getInt(const std::string& name, long fallback, long lo, long hi) const;
  double getDouble(const std::string& name, double fallback, double lo, double hi) const;
  // A comma-separated list of exactly `count` numbers ("--euler-zyz 10,20,30").
  std::vector<double> getDoubles(const std::string& name, size_t count) const;
  // The value must be one of `choices`.
  std::string getChoice(const std::string& name, const std::string& fallback,
                        const std::vector<std::string>& choices) const;
  // Global options shared by every command.
  std::string device() const { return get("device"); }
  bool quiet() const { return has("quiet"); }
};

struct Command {
  std::string name;
  std::string synopsis;  // one line, shown by `prtbake --help`
  std::string usage;     // shown by `prtbake NAME --help`
  std::vector<OptionSpec> options;
  size_t minPositional = 0, maxPositional = 0;
  std::function<int(const CommandLine&)> run;
};

std::vector<Command>& registry();

struct Registrar {
  explicit Registrar(Command c) { registry().push_back(std::move(c)); }
};

// Prints "prtbake: <text>" to stderr unless quiet (status lines, not errors).
void status(const CommandLine& cl, const std::string& text);

// Writes every file of `files` (path, bytes) together after creating the directory `dir`: each is
// staged first, then all are committed, so that a failure leaves none of them (OutputError).
void writeOutputsTogether(const std::string& dir, const std::vector<std::pair<std::string, std::string>>& files);

// The options of product `type`: the keys of its job type (jobs.h, declared once there) as
// --name with their help, range and default; then `extra`, the command's own (its outputs).
std::vector<OptionSpec> productOptions(const std::string& type, std::vector<OptionSpec> extra);

// The command-line names (without "--") of product `a`'s options that `b` does not have.
std::vector<std::string> optionsOnlyOf(const std::string& a, const std::string& b);

// `path` without the extension of its file name ("out/t.npy" -> "out/t"), and the sidecar JSON
// a command writes beside an output named `path` ("out/t.json").
std::string stem(const std::string& path);
std::string sidecarPath(const std::string& path);

// The command line's texts of keys: every option, named as a key ("bounce_tolerance").
std::map<std::string, std::string> keyTexts(const CommandLine& cl);

// The normalised parameters of product `type` from `texts` (default: keyTexts(cl)), checked as
// a job's are and with the type's rules run on `outputs`, the output kinds this command writes
// (jobs::paramsFromText); the first problem is a UsageError naming the option. An output that
// would replace one of `inputs` (default: the positional arguments) or a file that an option
// names (an environment) is a UsageError naming the output.
nlohmann::json productParams(const std::string& type, const std::map<std::string, std::string>& texts,
                             const nlohmann::json& outputs, std::vector<std::string> inputs = {});
nlohmann::json productParams(const CommandLine& cl, const std::string& type, const nlohmann::json& outputs);

}  // namespace prtbake::cli

#define PRTBAKE_CLI_CONCAT2(a, b) a##b
#define PRTBAKE_CLI_CONCAT(a, b) PRTBAKE_CLI_CONCAT2(a, b)
#define PRTBAKE_COMMAND(...) \
  static ::prtbake::cli::Registrar PRTBAKE_CLI_CONCAT(prtbakeCommand, __LINE__)(__VA_ARGS__)
