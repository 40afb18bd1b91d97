// A product's options, declared once: each is a key of the product's job type (name, kind,
// default, range or values, help) and the same declaration makes the command's option
// (`--bounce-tolerance` for the key `bounce_tolerance`), its help line, its check and
// docs/jobs.md's table (`prtbake keys`). The job validator and the command line both read a
// value through checkValue, and both run the job type's cross-key rules, so that the two can
// neither accept nor refuse differently.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace prtbake::jobs {

using nlohmann::json;

// Path: a file that must exist, relative paths resolved like `input`. NumberList: a JSON
// array of 1 to 16 numbers, each in [lo, hi] (on the command line: comma-separated).
// ChoiceList: one of `choices` or several joined by commas.
enum class ValueKind { Integer, Number, Boolean, Choice, ChoiceList, Path, NumberList };

// One option of a product, named as its job key.
struct KeySpec {
  std::string name;
  ValueKind kind;
  json defaultValue;                 // null: the key is optional and has no default
  double lo = 0, hi = 0;             // inclusive range of Integer, Number and NumberList keys
  std::vector<std::string> choices;  // the values of a Choice or ChoiceList key
  std::string help;                  // one line, for --help and docs/jobs.md
  bool onCommandLine = true;         // false: a job key only (a job's preview input)
  bool orAuto = false;               // an Integer key that also takes the word "auto"

  // The option's name on the command line: "--" and the key with '-' for '_'.
  std::string cliName() const;
};

KeySpec integer(const std::string& name, json def, double lo, double hi, std::string help);
KeySpec number(const std::string& name, json def, double lo, double hi, std::string help);
KeySpec boolean(const std::string& name, std::string help);  // default false; a flag on the command line
KeySpec choice(const std::string& name, const std::string& def, std::vector<std::string> choices, std::string help);

// Checks one value against its key; returns the problem text or "", and the normalised
// value (integers as integers) in *normalised.
std::string checkValue(const KeySpec& k, const json& v, json* normalised);

// A command-line value as the JSON a job file would hold: a number when the text is one
// ("3", "1e-3"), an array for a NumberList's commas, true for a flag, else the text.
json cliValue(const KeySpec& k, const std::string& text);

// Problems found while checking: {key, what}.
using KeyProblems = std::vector<std::pair<std::string, std::string>>;

// Every key of `keys` with its value in `given` (checked and normalised) or its default.
json normalise(const std::vector<KeySpec>& keys, const json& given, KeyProblems* problems);

// "a|b|c", for messages.
std::string joinChoices(const std::vector<std::string>& v, const char* sep = "|");

// Yaw is an angle about +Y in degrees; more than a turn either way is a mistake.
constexpr double kMaxYawDegrees = 360;

}  // namespace prtbake::jobs
