#include "tool_args.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>

namespace cfl::tool {

std::optional<std::string> ParsedArgs::get(const std::string& name) const {
  auto it = values.find(name);
  if (it == values.end()) return std::nullopt;
  return it->second;
}

ParsedArgs parseArgs(const std::vector<std::string>& args, std::vector<OptionSpec> spec) {
  spec.push_back({"help", false});
  auto find = [&](const std::string& name) -> const OptionSpec* {
    for (const auto& s : spec) {
      if (s.name == name) return &s;
    }
    return nullptr;
  };
  ParsedArgs out;
  bool options_done = false;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& word = args[i];
    if (options_done || word.size() < 2 || word[0] != '-' || (word[1] != '-' && word != "-h")) {
      // A lone "-" (standard input) and negative numbers are positionals.
      out.positionals.push_back(word);
      continue;
    }
    if (word == "--") {
      options_done = true;
      continue;
    }
    if (word == "-h") {
      out.values["help"] = "";
      continue;
    }
    std::string name = word.substr(2);
    std::optional<std::string> value;
    if (auto eq = name.find('='); eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
    }
    const OptionSpec* option = find(name);
    if (option == nullptr) throw UsageError("unknown option '--" + name + "'");
    if (!option->takes_value) {
      if (value) throw UsageError("option '--" + name + "' takes no value (got '" + *value + "')");
      out.values[name] = "";
      continue;
    }
    if (!value) {
      if (i + 1 >= args.size()) throw UsageError("option '--" + name + "' needs a value");
      value = args[++i];
    }
    out.values[name] = *value;
  }
  return out;
}

std::int64_t parseInteger(const std::string& text, const std::string& what, std::int64_t min, std::int64_t max) {
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE || v < min || v > max) {
    throw UsageError(what + ": expected an integer in [" + std::to_string(min) + ", " + std::to_string(max) +
                     "], got '" + text + "'");
  }
  return v;
}

double parseReal(const std::string& text, const std::string& what, double min, double max) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v) || v < min || v > max) {
    throw UsageError(what + ": expected a number in [" + std::to_string(min) + ", " + std::to_string(max) +
                     "], got '" + text + "'");
  }
  return v;
}

std::vector<double> parseBandList(const std::string& text, const std::string& what) {
  std::vector<double> out;
  std::size_t start = 0;
  for (int item = 1;; ++item) {
    const std::size_t comma = text.find(',', start);
    const std::string word = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    if (word.empty()) throw UsageError(what + ": item " + std::to_string(item) + " is empty in '" + text + "'");
    errno = 0;
    char* end = nullptr;
    const double v = std::strtod(word.c_str(), &end);
    if (end != word.c_str() + word.size() || !std::isfinite(v) || v < 0) {
      throw UsageError(what + ": item " + std::to_string(item) + " ('" + word +
                       "') is not a finite number >= 0");
    }
    out.push_back(v);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

}  // namespace cfl::tool
