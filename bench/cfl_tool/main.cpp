// The `cfl` command-line tool: build, inspect and benchmark CFL models against FCL.
// Exit status: 0 success, 1 failure (bad input file, failed check), 2 command-line usage error.

#include "cfl/error.h"
#include "commands.h"
#include "tool_args.h"

#include <exception>
#include <iostream>
#include <string>
#include <vector>

namespace {

constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;

void printUsage(std::ostream& out) {
  out << "usage: cfl COMMAND [ARGS...]    (cfl COMMAND --help for details)\n\n"
         "Exact mesh-mesh distance from discrete Voronoi regions (closest feature lists).\n\ncommands:\n";
  for (const auto& c : cfl::tool::commands()) out << "  " << c.name << std::string(10 - std::string(c.name).size(), ' ') << c.summary << '\n';
  out << "\nMeshes: any format assimp reads (OBJ, STL, PLY, OFF, glTF, Collada, ...).\n"
         "Exit status: 0 success; 1 failure (unreadable or invalid input, failed exactness check); 2 usage error.\n";
}

}  // namespace

int main(int argc, char** argv) {
  std::ios::sync_with_stdio(false);
  if (argc < 2) {
    printUsage(std::cerr);
    return kExitUsage;
  }
  const std::string name = argv[1];
  if (name == "--help" || name == "-h" || name == "help") {
    printUsage(std::cout);
    return 0;
  }
  const cfl::tool::Command* command = nullptr;
  for (const auto& c : cfl::tool::commands()) {
    if (name == c.name) command = &c;
  }
  if (command == nullptr) {
    std::cerr << "cfl: unknown command '" << name << "'\n\n";
    printUsage(std::cerr);
    return kExitUsage;
  }
  const std::vector<std::string> args(argv + 2, argv + argc);
  try {
    return command->run(args, {std::cin, std::cout, std::cerr});
  } catch (const cfl::tool::UsageError& e) {
    std::cout.flush();
    std::cerr << "cfl " << name << ": " << e.what() << "\n(see 'cfl " << name << " --help')\n";
    return kExitUsage;
  } catch (const cfl::Error& e) {
    std::cout.flush();
    std::cerr << "cfl " << name << ": error: " << e.what() << '\n';
    return kExitFailure;
  } catch (const std::exception& e) {
    std::cout.flush();
    std::cerr << "cfl " << name << ": error: " << e.what() << '\n';
    return kExitFailure;
  }
}
