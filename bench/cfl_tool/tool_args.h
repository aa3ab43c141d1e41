#pragma once
/// @file
/// Command-line parsing of the `cfl` tool: options, numbers and lists, with errors that name the option.

#include <cstdint>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace cfl::tool {

/// A mistake in the command line itself (unknown option, missing or malformed value). The tool prints the
/// message and the subcommand's usage and exits with status 2; every other failure exits with 1.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One accepted option: "--name" alone (a flag) or followed by a value ("--name V" or "--name=V").
struct OptionSpec {
  std::string name;  ///< Without the leading dashes.
  bool takes_value = true;
};

/// A parsed command line: positional arguments in order and the options seen (a repeated option keeps its
/// last value).
struct ParsedArgs {
  std::vector<std::string> positionals;
  std::map<std::string, std::string> values;  ///< Flags map to "".

  bool has(const std::string& name) const { return values.count(name) > 0; }
  std::optional<std::string> get(const std::string& name) const;
};

/// Parses `args` (the words after the subcommand). "--" ends the options; "-h" means "--help", which every
/// subcommand accepts. Throws UsageError naming the offending word for an unknown option, a value given to
/// a flag, or a missing value.
ParsedArgs parseArgs(const std::vector<std::string>& args, std::vector<OptionSpec> spec);

/// Parses the whole of `text` as an integer in [min, max]; UsageError naming `what` otherwise.
std::int64_t parseInteger(const std::string& text, const std::string& what, std::int64_t min, std::int64_t max);

/// Parses the whole of `text` as a finite double in [min, max]; UsageError naming `what` otherwise.
double parseReal(const std::string& text, const std::string& what, double min, double max);

/// Parses a comma-separated list of finite doubles >= 0, such as "0,0.005,0.02". Empty items, trailing
/// commas and an empty list are errors; the message names the item's position (1-based) and text.
std::vector<double> parseBandList(const std::string& text, const std::string& what);

}  // namespace cfl::tool
