// prtbake: entry point. Parses the command line, dispatches to a subcommand and
// maps exceptions to exit codes: 0 success, 1 failed job / bad input, 2 usage.
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <memory>
#include <string>

#include "cli.h"
#include "jobs.h"
#include "prtbake/atomic_file.h"
#include "prtbake/error.h"
#include "prtbake/runtime.h"

namespace prtbake::cli {

std::vector<Command>& registry() {
  static std::vector<Command> commands;
  return commands;
}

namespace {

const std::vector<OptionSpec> kCommonOptions = {
    {"device", true, "OpenCL device: auto, cpu, gpu or an index (default: $PRTBAKE_DEVICE or auto)"},
    {"quiet", false, "print only errors"},
    {"progress", false, "show progress even when stderr is not a terminal"},
    {"log-json", false, "print machine-readable JSON events on stderr"},
    {"help", false, "show this help"},
};

void printOptions(const std::vector<OptionSpec>& options) {
  for (const auto& o : options) {
    std::string left = "  --" + o.name + (o.takesValue ? " VALUE" : "");
    if (left.size() < 30) left.resize(30, ' ');
    std::cout << left << " " << o.help << "\n";
  }
}

void printTopHelp() {
  std::cout << "prtbake " << version()
            << ": SH environment lighting, PRT transport, BRDF lookup tables and prefiltered environments on OpenCL\n\n"
               "usage: prtbake COMMAND [ARGS] [OPTIONS]\n\ncommands:\n";
  auto commands = registry();
  std::sort(commands.begin(), commands.end(),
            [](const Command& a, const Command& b) { return a.name < b.name; });
  for (const auto& c : commands) {
    std::string left = "  " + c.name;
    left.resize(14, ' ');
    std::cout << left << c.synopsis << "\n";
  }
  std::cout << "\ncommon options:\n";
  printOptions(kCommonOptions);
  std::cout << "  --version                      print the version\n"
               "\nRun 'prtbake COMMAND --help' for a command's options.\n";
}

const Command* findCommand(const std::string& name) {
  for (const auto& c : registry())
    if (c.name == name) return &c;
  return nullptr;
}

CommandLine parse(const Command& cmd, int argc, char** argv) {
  CommandLine cl;
  cl.command = cmd.name;
  auto spec = [&](const std::string& name) -> const OptionSpec* {
    for (const auto& o : cmd.options)
      if (o.name == name) return &o;
    for (const auto& o : kCommonOptions)
      if (o.name == name) return &o;
    return nullptr;
  };
  bool optionsEnded = false;
  for (int i = 2; i < argc; ++i) {
    std::string arg = argv[i];
    if (!optionsEnded && arg == "--") {
      optionsEnded = true;
      continue;
    }
    if (!optionsEnded && arg.size() > 1 && arg[0] == '-' && !(arg.size() > 1 && std::isdigit(arg[1]))) {
      std::string name, value;
      bool hasValue = false;
      if (arg.rfind("--", 0) == 0) {
        name = arg.substr(2);
      } else if (arg == "-o") {
        name = "output";
      } else if (arg == "-q") {
        name = "quiet";
      } else {
        throw UsageError(cmd.name, "unknown option '" + arg + "'");
      }
      if (auto eq = name.find('='); eq != std::string::npos) {
        value = name.substr(eq + 1);
        name = name.substr(0, eq);
        hasValue = true;
      }
      const OptionSpec* o = spec(name);
      if (!o) throw UsageError(cmd.name, "unknown option '--" + name + "' (see prtbake " + cmd.name + " --help)");
      if (o->takesValue && !hasValue) {
        if (i + 1 >= argc) throw UsageError(cmd.name, "option '--" + name + "' needs a value");
        value = argv[++i];
      } else if (!o->takesValue && hasValue) {
        throw UsageError(cmd.name, "option '--" + name + "' takes no value");
      }
      if (cl.options.count(name)) throw UsageError(cmd.name, "option '--" + name + "' given twice");
      cl.options[name] = value;
    } else {
      cl.positional.push_back(arg);
    }
  }
  if (cl.has("help")) return cl;
  if (cl.positional.size() < cmd.minPositional)
    throw UsageError(cmd.name, "missing argument (usage: " + cmd.usage.substr(0, cmd.usage.find('\n')) + ")");
  if (cl.positional.size() > cmd.maxPositional)
    throw UsageError(cmd.name, "unexpected argument '" + cl.positional[cmd.maxPositional] + "'");
  return cl;
}

}  // namespace

std::string CommandLine::get(const std::string& name, const std::string& fallback) const {
  auto it = options.find(name);
  return it == options.end() ? fallback : it->second;
}

long CommandLine::getInt(const std::string& name, long fallback, long lo, long hi) const {
  auto it = options.find(name);
  if (it == options.end()) return fallback;
  errno = 0;
  char* end = nullptr;
  const long v = std::strtol(it->second.c_str(), &end, 10);
  if (it->second.empty() || *end != '\0' || errno == ERANGE)
    throw UsageError("--" + name, "expected an integer, got '" + it->second + "'");
  if (v < lo || v > hi)
    throw UsageError("--" + name, std::to_string(v) + " is out of range [" + std::to_string(lo) + ", " +
                                      std::to_string(hi) + "]");
  return v;
}

double CommandLine::getDouble(const std::string& name, double fallback, double lo, double hi) const {
  auto it = options.find(name);
  if (it == options.end()) return fallback;
  char* end = nullptr;
  const double v = std::strtod(it->second.c_str(), &end);
  if (it->second.empty() || *end != '\0' || !std::isfinite(v))
    throw UsageError("--" + name, "expected a finite number, got '" + it->second + "'");
  if (v < lo || v > hi)
    throw UsageError("--" + name, it->second + " is out of range [" + std::to_string(lo) + ", " +
                                      std::to_string(hi) + "]");
  return v;
}

std::vector<double> CommandLine::getDoubles(const std::string& name, size_t count) const {
  const std::string text = get(name);
  std::vector<double> out;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = text.find(',', start);
    const std::string part = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    char* end = nullptr;
    const double v = std::strtod(part.c_str(), &end);
    if (part.empty() || *end != '\0' || !std::isfinite(v))
      throw UsageError("--" + name, "expected " + std::to_string(count) + " comma-separated numbers, got '" + text + "'");
    out.push_back(v);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (out.size() != count)
    throw UsageError("--" + name, "expected " + std::to_string(count) + " comma-separated numbers, got '" + text + "'");
  return out;
}

std::string CommandLine::getChoice(const std::string& name, const std::string& fallback,
                                   const std::vector<std::string>& choices) const {
  const std::string v = get(name, fallback);
  for (const auto& c : choices)
    if (c == v) return v;
  std::string list;
  for (const auto& c : choices) list += (list.empty() ? "" : "|") + c;
  throw UsageError("--" + name, "unknown value '" + v + "' (expected " + list + ")");
}

std::vector<OptionSpec> productOptions(const std::string& type, std::vector<OptionSpec> extra) {
  std::vector<OptionSpec> options;
  for (const auto& k : jobs::findJobType(type)->keys) {
    if (!k.onCommandLine) continue;
    const std::string range = jobs::describeRange(k);
    options.push_back({k.cliName().substr(2), k.kind != jobs::ValueKind::Boolean,
                       k.help + (range.empty() ? "" : " (" + range + ")")});
  }
  for (auto& o : extra) options.push_back(std::move(o));
  return options;
}

std::vector<std::string> optionsOnlyOf(const std::string& a, const std::string& b) {
  std::vector<std::string> names;
  const auto& other = jobs::findJobType(b)->keys;
  for (const auto& k : jobs::findJobType(a)->keys)
    if (k.onCommandLine && std::none_of(other.begin(), other.end(), [&](const jobs::KeySpec& o) { return o.name == k.name; }))
      names.push_back(k.cliName().substr(2));
  return names;
}

void writeOutputsTogether(const std::string& dir, const std::vector<std::pair<std::string, std::string>>& files) {
  if (::mkdir(dir.c_str(), 0777) != 0 && errno != EEXIST)
    throw OutputError(dir, std::string("cannot create the directory: ") + std::strerror(errno));
  std::vector<std::unique_ptr<AtomicFile>> staged;
  for (const auto& [path, bytes] : files) {
    staged.push_back(std::make_unique<AtomicFile>(path));
    staged.back()->write(bytes);
  }
  for (auto& f : staged) f->commit();
}

std::string stem(const std::string& path) {
  const size_t slash = path.find_last_of('/'), dot = path.find_last_of('.');
  return dot != std::string::npos && (slash == std::string::npos || dot > slash) ? path.substr(0, dot) : path;
}

std::string sidecarPath(const std::string& path) { return stem(path) + ".json"; }

std::map<std::string, std::string> keyTexts(const CommandLine& cl) {
  std::map<std::string, std::string> texts;
  for (const auto& [name, text] : cl.options) {
    std::string key = name;
    std::replace(key.begin(), key.end(), '-', '_');
    texts[key] = text;
  }
  return texts;
}

nlohmann::json productParams(const std::string& type, const std::map<std::string, std::string>& texts,
                             const nlohmann::json& outputs, std::vector<std::string> inputs) {
  jobs::KeyProblems problems;
  const jobs::JobType& t = *jobs::findJobType(type);
  nlohmann::json params = jobs::paramsFromText(t, texts, outputs, &problems);
  if (!problems.empty()) {
    const auto& [key, what] = problems.front();
    std::string option = key == "outputs" ? type : "--" + key;
    std::replace(option.begin(), option.end(), '_', '-');
    throw UsageError(option, what);
  }
  for (const auto& k : t.keys)
    if (k.kind == jobs::ValueKind::Path && texts.count(k.name)) inputs.push_back(texts.at(k.name));
  std::vector<std::string> written, kinds;
  if (outputs.is_object())
    for (const auto& [kind, out] : outputs.items())
      if (out.is_string()) written.push_back(out.get<std::string>()), kinds.push_back(kind);
  for (size_t i = 0; i < written.size(); ++i)  // one output would replace the other
    for (size_t j = 0; j < i; ++j)
      if (jobs::sameFile(written[j], written[i]))
        throw UsageError(written[i], "is both the " + kinds[j] + " and the " + kinds[i] + " output");
  jobs::checkOutputsSpareInputs(inputs, written);
  return params;
}

nlohmann::json productParams(const CommandLine& cl, const std::string& type, const nlohmann::json& outputs) {
  return productParams(type, keyTexts(cl), outputs, cl.positional);
}

void status(const CommandLine& cl, const std::string& text) {
  if (!cl.quiet()) std::cerr << "prtbake: " << text << "\n";
}

}  // namespace prtbake::cli

int main(int argc, char** argv) {
  using namespace prtbake;
  using namespace prtbake::cli;
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h" ||
      std::string(argv[1]) == "help") {
    printTopHelp();
    return argc < 2 ? 2 : 0;
  }
  if (std::string(argv[1]) == "--version") {
    std::cout << "prtbake " << version() << "\n";
    return 0;
  }
  const Command* cmd = findCommand(argv[1]);
  if (!cmd) {
    std::cerr << "prtbake: error: unknown command '" << argv[1] << "' (see prtbake --help)\n";
    return 2;
  }
  try {
    CommandLine cl = parse(*cmd, argc, argv);
    if (cl.has("help")) {
      std::cout << "usage: " << cmd->usage << "\n\noptions:\n";
      printOptions(cmd->options);
      printOptions(kCommonOptions);
      return 0;
    }
    return cmd->run(cl);
  } catch (const UsageError& e) {
    std::cerr << "prtbake: error: " << e.what() << "\n";
    return 2;
  } catch (const Error& e) {
    std::cerr << "prtbake: error: " << e.what() << "\n";
    return 1;
  } catch (const cl::Error& e) {
    std::cerr << "prtbake: error: " << Error::oneLine(describeClError(e, lastDeviceLabel())) << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "prtbake: error: out of host memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "prtbake: error: " << e.what() << "\n";
    return 1;
  }
}
