#pragma once
/// @file
/// The subcommands of the `cfl` tool. Each takes the words after its name and returns the exit status
/// (0 success, 1 failure); command-line mistakes throw UsageError (status 2) and bad input cfl::Error
/// (status 1), both reported by main.

#include <iosfwd>
#include <string>
#include <vector>

namespace cfl::tool {

struct Streams {
  std::istream& in;
  std::ostream& out;
  std::ostream& err;
};

/// One subcommand: its name, one-line summary and entry point (which prints its usage for --help).
struct Command {
  const char* name;
  const char* summary;
  int (*run)(const std::vector<std::string>& args, Streams io);
};

/// Every subcommand, in the order `cfl --help` lists them.
const std::vector<Command>& commands();

int runBuild(const std::vector<std::string>& args, Streams io);
int runInfo(const std::vector<std::string>& args, Streams io);
int runDistance(const std::vector<std::string>& args, Streams io);
int runSdf(const std::vector<std::string>& args, Streams io);
int runBench(const std::vector<std::string>& args, Streams io);
int runPaper(const std::vector<std::string>& args, Streams io);
int runSuite(const std::vector<std::string>& args, Streams io);

}  // namespace cfl::tool
