// Helpers for tests that run the `cfl` binary (named by CFL_TOOL_PATH) as a subprocess: a temporary
// directory per test, the tool's exit status and captured stdout/stderr, and small file helpers.
// tool_cli_test and suite_cli_test used to carry identical copies of these; keep them here instead.

#ifndef CFL_TESTS_TOOL_TOOL_PROCESS_H
#define CFL_TESTS_TOOL_TOOL_PROCESS_H

#include "cfl/mesh.h"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#ifndef CFL_TOOL_PATH
#error "CFL_TOOL_PATH must name the cfl binary"
#endif

namespace cfl::tool_test {

// What one run of the tool produced.
struct ToolRun {
  int status = -1;  // exit status, or -1 when the tool did not exit normally
  std::string out;
  std::string err;
};

inline std::string readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void writeFile(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// `word` as one single-quoted shell word.
inline std::string quote(const std::string& word) {
  std::string q = "'";
  for (char c : word) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

inline bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// `m` as OBJ text, coordinates printed exactly.
inline std::string objText(const TriangleMesh& m) {
  std::string s;
  char line[128];
  for (const auto& v : m.vertices) {
    std::snprintf(line, sizeof line, "v %.17g %.17g %.17g\n", v.x(), v.y(), v.z());
    s += line;
  }
  for (const auto& t : m.triangles) {
    s += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " + std::to_string(t[2] + 1) + "\n";
  }
  return s;
}

// Runs the tool with `args` (shell words, quoted here) and standard input from the file `stdin_path`;
// stdout and stderr go through dir/stdout.txt and dir/stderr.txt. `env`, when not empty, is passed to
// /usr/bin/env ahead of the tool (e.g. "NAME=value").
inline ToolRun runTool(const std::string& dir, const std::vector<std::string>& args,
                       const std::string& stdin_path = "/dev/null", const std::string& env = "") {
  const std::string out_path = dir + "/stdout.txt", err_path = dir + "/stderr.txt";
  std::string command = env.empty() ? "" : "/usr/bin/env " + env + " ";
  command += quote(CFL_TOOL_PATH);
  for (const auto& a : args) command += " " + quote(a);
  command += " < " + quote(stdin_path) + " > " + quote(out_path) + " 2> " + quote(err_path);
  const int raw = std::system(command.c_str());
  ToolRun r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = readFile(out_path);
  r.err = readFile(err_path);
  return r;
}

// A fixture owning a fresh temporary directory, named from `prefix`, removed after each test.
class ToolTempDirTest : public ::testing::Test {
 protected:
  explicit ToolTempDirTest(std::string prefix) : prefix_(std::move(prefix)) {}

  void SetUp() override {
    std::string pattern = ::testing::TempDir() + prefix_ + "XXXXXX";
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }
  void TearDown() override { std::system(("rm -rf " + quote(dir_)).c_str()); }
  std::string path(const std::string& name) const { return dir_ + "/" + name; }

  std::string dir_;

 private:
  std::string prefix_;
};

}  // namespace cfl::tool_test

#endif  // CFL_TESTS_TOOL_TOOL_PROCESS_H
