// Each product's options are declared once (service/options.h) and read by both the job
// validator and the command line. These tests walk every key of every job type and check
// that a job file and a command line accept and refuse the same values, with the same
// parameters, alone and two at a time (the cross-key rules); that every command lists every
// key as its option; and that docs/jobs.md holds the tables `prtbake keys` prints.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <sstream>

#include "jobs.h"
#include "options.h"
#include "test_common.h"

namespace prtbake::test {
namespace {

using jobs::json;
using jobs::KeySpec;
using jobs::ValueKind;

// One value of a key, as a job file writes it and as a command line does.
struct Value {
  json job;
  std::string text;
};

std::string numberText(double v) {
  std::ostringstream ss;
  ss.precision(17);
  ss << v;
  return ss.str();
}

Value numeric(double v) {
  if (v == std::floor(v) && std::fabs(v) < 1e15) return {json(static_cast<long long>(v)), numberText(v)};
  return {json(v), numberText(v)};
}

// Values in range, at its ends, just outside them and of the wrong kind.
std::vector<Value> probeValues(const KeySpec& k) {
  std::vector<Value> v;
  switch (k.kind) {
    case ValueKind::Integer:
      v = {numeric(k.lo), numeric(k.hi), numeric(std::floor((k.lo + k.hi) / 2)), numeric(k.lo - 1),
           numeric(k.hi + 1), {json(k.lo + 0.5), numberText(k.lo + 0.5)}, {json("many"), "many"}};
      if (k.orAuto) v.push_back({json("auto"), "auto"});
      break;
    case ValueKind::Number: {
      const double step = std::max(std::fabs(k.hi - k.lo) * 1e-3, 1e-12);
      v = {numeric(k.lo), numeric(k.hi), numeric((k.lo + k.hi) / 2), numeric(k.lo - step), numeric(k.hi + step),
           {json("much"), "much"}};
      break;
    }
    case ValueKind::Boolean:
      v = {{json(true), ""}};  // a flag: present is true
      break;
    case ValueKind::Choice:
      for (const auto& c : k.choices) v.push_back({json(c), c});
      v.push_back({json("bogus"), "bogus"});
      v.push_back({json(k.choices.front() + "x"), k.choices.front() + "x"});
      break;
    case ValueKind::ChoiceList:
      for (const auto& c : k.choices) v.push_back({json(c), c});
      v.push_back({json(k.choices[1] + "," + k.choices.back()), k.choices[1] + "," + k.choices.back()});
      v.push_back({json(k.choices[1] + ",bogus"), k.choices[1] + ",bogus"});
      break;
    case ValueKind::NumberList:
      v = {{json::array({k.lo, k.hi}), numberText(k.lo) + "," + numberText(k.hi)},
           {json::array({k.hi + 1}), numberText(k.hi + 1)},
           {json::array({"a"}), "a"}};
      break;
    case ValueKind::Path:
      break;
  }
  return v;
}

// The outputs every case of a type asks for (one that each type accepts alone).
json outputsFor(const jobs::JobType& t, const std::string& dir, int index) {
  const std::string kind = t.name == "prefilter" ? "ktx2" : t.outputKinds.front();
  return {{kind, dir + "/out" + std::to_string(index) + "." + kind}};
}

struct Case {
  std::map<std::string, std::string> texts;
  json given = json::object();
};

// Validates every case both ways and compares: accepted by both with equal parameters, or
// refused by both (the job's problems name a key the command line's problem names too).
void compare(const jobs::JobType& t, const std::vector<Case>& cases, const std::string& dir) {
  const std::string input = dir + "/input.bin";
  std::ofstream(input) << "x";
  json file = {{"jobs", json::array()}};
  for (size_t i = 0; i < cases.size(); ++i) {
    json job = cases[i].given;
    job["id"] = "case" + std::to_string(i);
    job["type"] = t.name;
    if (t.input != jobs::InputKind::None) job["input"] = input;
    job["outputs"] = outputsFor(t, dir, int(i));
    file["jobs"].push_back(job);
  }
  const std::string path = dir + "/" + t.name + ".json";
  std::ofstream(path) << file.dump(1);
  const jobs::JobFile loaded = jobs::loadJobFile(path);
  REQUIRE(loaded.fileProblems.empty());
  REQUIRE(loaded.jobs.size() == cases.size());
  for (size_t i = 0; i < cases.size(); ++i) {
    jobs::KeyProblems cliProblems;
    json cliParams = jobs::paramsFromText(t, cases[i].texts, outputsFor(t, dir, int(i)), &cliProblems);
    const jobs::Job& job = loaded.jobs[i];
    INFO(t.name << " " << cases[i].given.dump() << ": job problems " << job.problems.size()
                << (job.problems.empty() ? "" : " (" + job.problems[0].key + ": " + job.problems[0].what + ")")
                << ", command line problems " << cliProblems.size()
                << (cliProblems.empty() ? "" : " (" + cliProblems[0].first + ": " + cliProblems[0].second + ")"));
    REQUIRE(job.valid() == cliProblems.empty());
    if (job.valid()) {
      for (const auto& k : t.keys)
        if (k.onCommandLine) CHECK(job.params[k.name] == cliParams[k.name]);
    } else {
      CHECK(job.problems.front().key == cliProblems.front().first);
    }
  }
}

TEST_CASE("Every key of every job type: a job file and the command line accept and refuse the same values",
          "[options]") {
  const std::string dir = tempDir("options-values");
  size_t checked = 0, refused = 0;
  for (const auto& t : jobs::jobTypes()) {
    std::vector<Case> cases;
    for (const auto& k : t.keys) {
      if (!k.onCommandLine) continue;
      for (const auto& v : probeValues(k)) {
        Case c;
        c.texts[k.name] = v.text;
        c.given[k.name] = v.job;
        cases.push_back(c);
      }
    }
    compare(t, cases, dir);
    checked += cases.size();
    for (const auto& j : jobs::loadJobFile(dir + "/" + t.name + ".json").jobs) refused += !j.valid();
  }
  // The probes must reach both answers: a walk that accepted or refused everything proves nothing.
  CHECK(checked > 200);
  CHECK(refused > checked / 4);
  CHECK(refused < checked);
}

TEST_CASE("Every two keys of every job type given together: the cross-key rules agree", "[options]") {
  const std::string dir = tempDir("options-pairs");
  size_t refused = 0, total = 0;
  for (const auto& t : jobs::jobTypes()) {
    // Each key at a valid value of its own: the first probe (the low end, a choice, true).
    std::vector<std::pair<const KeySpec*, Value>> valid;
    for (const auto& k : t.keys)
      if (k.onCommandLine && !probeValues(k).empty()) valid.push_back({&k, probeValues(k).front()});
    std::vector<Case> cases;
    for (size_t a = 0; a < valid.size(); ++a)
      for (size_t b = a + 1; b < valid.size(); ++b) {
        Case c;
        for (const auto& [k, v] : {valid[a], valid[b]}) {
          c.texts[k->name] = v.text;
          c.given[k->name] = v.job;
        }
        cases.push_back(c);
      }
    compare(t, cases, dir);
    total += cases.size();
    for (const auto& j : jobs::loadJobFile(dir + "/" + t.name + ".json").jobs) refused += !j.valid();
  }
  CHECK(total > 300);
  CHECK(refused > 10);  // the rules do refuse some pairs (samples with tolerance, ...)
}

TEST_CASE("A refused value is refused alike by the prtbake command and by prtbake run", "[options]") {
  // The command line's own path (option parsing, productParams), not only the shared checks.
  const std::string dir = tempDir("options-cli");
  std::ofstream(dir + "/sky.hdr") << "x";
  const CliResult cli = runCli("env '" + dir + "/sky.hdr' -o '" + dir + "/out.json' --yaw 400");
  CHECK(cli.exitCode == 2);
  CHECK(cli.output.find("--yaw: 400 is out of range [-360, 360]") != std::string::npos);
  std::ofstream(dir + "/job.json") << json{{"jobs", {{{"id", "a"}, {"type", "env"}, {"input", "sky.hdr"},
                                                     {"outputs", {{"json", "out.json"}}}, {"yaw", 400}}}}}.dump();
  const CliResult run = runCli("run '" + dir + "/job.json'");
  CHECK(run.exitCode != 0);
  CHECK(run.output.find("yaw: 400 is out of range [-360, 360]") != std::string::npos);
  const CliResult lut = runCli("lut -o '" + dir + "/lut.exr' --samples 16 --tolerance 0.01");
  CHECK(lut.exitCode == 2);
  CHECK(lut.output.find("--tolerance: cannot be combined with samples") != std::string::npos);
}

TEST_CASE("Every command lists every key of its product as an option", "[options]") {
  const std::map<std::string, std::string> command = {{"env", "env"},     {"transport", "transport"},
                                                      {"glossy", "transport"}, {"lut", "lut"},
                                                      {"prefilter", "prefilter"}, {"ibl", "ibl"},
                                                      {"probes", "probes"}, {"lightmap", "lightmap"}};
  for (const auto& t : jobs::jobTypes()) {
    const CliResult help = runCli(command.at(t.name) + " --help");
    REQUIRE(help.exitCode == 0);
    for (const auto& k : t.keys) {
      INFO(t.name << ": " << k.cliName());
      CHECK((!k.onCommandLine || help.output.find("  " + k.cliName() + " ") != std::string::npos));
    }
  }
}

TEST_CASE("docs/jobs.md holds the key tables that prtbake keys prints", "[options]") {
  std::ifstream in(std::string(PRTBAKE_TEST_SOURCE_DIR) + "/../docs/jobs.md");
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string docs = ss.str();
  const std::string begin = "<!-- prtbake keys: begin -->\n", end = "<!-- prtbake keys: end -->";
  const size_t a = docs.find(begin), b = docs.find(end);
  REQUIRE(a != std::string::npos);
  REQUIRE(b != std::string::npos);
  const CliResult keys = runCli("keys");
  REQUIRE(keys.exitCode == 0);
  INFO("regenerate with: prtbake keys, between the markers in docs/jobs.md");
  CHECK(docs.substr(a + begin.size(), b - a - begin.size()) == keys.output);
}

}  // namespace
}  // namespace prtbake::test
