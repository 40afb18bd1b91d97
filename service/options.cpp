// Product options declared once (see options.h): checking a value, reading one from the
// command line, and filling a product's parameters.
#include "options.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cctype>
#include <cstdlib>
#include <sstream>

#include "jobs.h"

namespace prtbake::jobs {
namespace {

// A JSON value as it appeared, shortened for messages.
std::string shown(const json& v) {
  std::string s = v.dump();
  if (s.size() > 40) s = s.substr(0, 37) + "...";
  return s;
}

std::string formatNumber(double v) {
  std::ostringstream ss;
  ss.precision(12);
  ss << v;
  return ss.str();
}

std::string outOfRange(const KeySpec& k, double d) {
  return formatNumber(d) + " is out of range [" + formatNumber(k.lo) + ", " + formatNumber(k.hi) + "]";
}

std::string unknownChoice(const KeySpec& k, const std::string& s) {
  const std::string near = closestMatch(s, k.choices);
  return "unknown value '" + s + "' (expected " + joinChoices(k.choices) + ")" +
         (near.empty() ? "" : "; did you mean '" + near + "'?");
}

// The number a whole command-line text holds, if it is one.
bool parseNumber(const std::string& text, double* v) {
  if (text.empty() || std::isspace(static_cast<unsigned char>(text[0])) ||
      text.find_first_of("xX") != std::string::npos)  // no hexadecimal
    return false;
  char* end = nullptr;
  *v = std::strtod(text.c_str(), &end);
  return *end == '\0';
}

}  // namespace

std::string KeySpec::cliName() const {
  std::string s = "--" + name;
  std::replace(s.begin(), s.end(), '_', '-');
  return s;
}

KeySpec integer(const std::string& name, json def, double lo, double hi, std::string help) {
  return {name, ValueKind::Integer, std::move(def), lo, hi, {}, std::move(help)};
}
KeySpec number(const std::string& name, json def, double lo, double hi, std::string help) {
  return {name, ValueKind::Number, std::move(def), lo, hi, {}, std::move(help)};
}
KeySpec boolean(const std::string& name, std::string help) {
  return {name, ValueKind::Boolean, false, 0, 0, {}, std::move(help)};
}
KeySpec choice(const std::string& name, const std::string& def, std::vector<std::string> choices, std::string help) {
  return {name, ValueKind::Choice, def, 0, 0, std::move(choices), std::move(help)};
}

std::string joinChoices(const std::vector<std::string>& v, const char* sep) {
  std::string s;
  for (const auto& c : v) s += (s.empty() ? "" : sep) + c;
  return s;
}

std::string checkValue(const KeySpec& k, const json& v, json* normalised) {
  switch (k.kind) {
    case ValueKind::Integer: {
      if (k.orAuto && v == "auto") {
        *normalised = v;
        return "";
      }
      const bool whole = v.is_number_integer() || v.is_number_unsigned() ||
                         (v.is_number_float() && std::isfinite(v.get<double>()) &&
                          v.get<double>() == std::floor(v.get<double>()));
      if (!whole) return std::string("expected an integer") + (k.orAuto ? " or auto" : "") + ", got " + shown(v);
      const double d = v.get<double>();
      if (d < k.lo || d > k.hi) return outOfRange(k, d);
      *normalised = static_cast<long long>(d);
      return "";
    }
    case ValueKind::Number: {
      if (!v.is_number()) return "expected a number, got " + shown(v);
      const double d = v.get<double>();
      if (!std::isfinite(d) || d < k.lo || d > k.hi) return outOfRange(k, d);
      *normalised = d;
      return "";
    }
    case ValueKind::Boolean:
      if (!v.is_boolean()) return "expected true or false, got " + shown(v);
      *normalised = v;
      return "";
    case ValueKind::Choice: {
      if (!v.is_string()) return "expected one of " + joinChoices(k.choices) + ", got " + shown(v);
      const std::string s = v.get<std::string>();
      if (std::find(k.choices.begin(), k.choices.end(), s) == k.choices.end()) return unknownChoice(k, s);
      *normalised = s;
      return "";
    }
    case ValueKind::ChoiceList: {
      if (!v.is_string() || v.get<std::string>().empty())
        return "expected " + joinChoices(k.choices) + " or a comma-separated list of them, got " + shown(v);
      const std::string s = v.get<std::string>();
      for (size_t start = 0; start <= s.size();) {
        const size_t comma = std::min(s.find(',', start), s.size());
        const std::string part = s.substr(start, comma - start);
        if (std::find(k.choices.begin(), k.choices.end(), part) == k.choices.end()) return unknownChoice(k, part);
        start = comma + 1;
      }
      *normalised = s;
      return "";
    }
    case ValueKind::Path:
      if (!v.is_string() || v.get<std::string>().empty()) return "expected a path, got " + shown(v);
      *normalised = v;
      return "";
    case ValueKind::NumberList: {
      if (!v.is_array() || v.empty() || v.size() > 16) return "expected an array of 1 to 16 numbers, got " + shown(v);
      json out = json::array();
      for (const json& x : v) {
        if (!x.is_number()) return "expected an array of 1 to 16 numbers, got " + shown(v);
        const double d = x.get<double>();
        if (!std::isfinite(d) || d < k.lo || d > k.hi) return outOfRange(k, d);
        out.push_back(d);
      }
      *normalised = out;
      return "";
    }
  }
  return "";
}

json cliValue(const KeySpec& k, const std::string& text) {
  double d = 0;
  switch (k.kind) {
    case ValueKind::Boolean:
      return true;
    case ValueKind::Integer:
    case ValueKind::Number:
      if (parseNumber(text, &d)) {
        // An integer text stays an integer (beyond 2^53 too); anything else is a double.
        const bool integral = text.find_first_of(".eEnN") == std::string::npos;
        if (integral && k.kind == ValueKind::Integer) {
          char* end = nullptr;
          errno = 0;
          const long long i = std::strtoll(text.c_str(), &end, 10);
          if (*end == '\0' && errno == 0) return i;
        }
        return d;
      }
      return text;
    case ValueKind::NumberList: {
      json list = json::array();
      for (size_t start = 0; start <= text.size();) {
        const size_t comma = std::min(text.find(',', start), text.size());
        const std::string part = text.substr(start, comma - start);
        if (!parseNumber(part, &d)) return text;  // refused by checkValue as it stands
        list.push_back(d);
        start = comma + 1;
      }
      return list;
    }
    default:
      return text;
  }
}

json normalise(const std::vector<KeySpec>& keys, const json& given, KeyProblems* problems) {
  json params = json::object();
  for (const auto& k : keys) {
    auto it = given.find(k.name);
    if (it == given.end()) {
      params[k.name] = k.defaultValue;
      continue;
    }
    json value;
    const std::string what = checkValue(k, *it, &value);
    if (!what.empty()) problems->push_back({k.name, what});
    params[k.name] = value;
  }
  return params;
}

json paramsFromText(const JobType& type, const std::map<std::string, std::string>& texts, const json& outputs,
                    KeyProblems* problems) {
  json given = json::object();
  for (const auto& k : type.keys)
    if (auto it = texts.find(k.name); it != texts.end() && k.onCommandLine) given[k.name] = cliValue(k, it->second);
  const size_t before = problems->size();
  json params = normalise(type.keys, given, problems);
  if (problems->size() == before && type.check) {
    json raw = given;
    raw["outputs"] = outputs;
    for (auto& p : type.check(raw, params)) problems->push_back(std::move(p));
  }
  return params;
}

std::string describeRange(const KeySpec& k) {
  std::string range;
  switch (k.kind) {
    case ValueKind::Integer:
    case ValueKind::Number:
      range = formatNumber(k.lo) + ".." + formatNumber(k.hi) + (k.orAuto ? " or auto" : "");
      break;
    case ValueKind::NumberList:
      range = "1 to 16 numbers in " + formatNumber(k.lo) + ".." + formatNumber(k.hi);
      break;
    case ValueKind::Choice:
      range = joinChoices(k.choices, ", ");
      break;
    case ValueKind::ChoiceList:
      range = joinChoices(k.choices, ", ") + " or a comma-separated list";
      break;
    case ValueKind::Boolean:
    case ValueKind::Path:
      break;
  }
  if (k.kind == ValueKind::Boolean) return "";
  if (k.defaultValue.is_null()) return range;
  const std::string def = k.defaultValue.is_string() ? k.defaultValue.get<std::string>()
                          : k.defaultValue.is_number_float() ? formatNumber(k.defaultValue.get<double>())
                                                             : k.defaultValue.dump();
  return range + (range.empty() ? "" : ", ") + "default " + def;
}

}  // namespace prtbake::jobs
