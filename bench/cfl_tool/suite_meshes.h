#pragma once
/// @file
/// The benchmark suite of `cfl suite`: meshes of the shapes users bring (issue 31), generated into a
/// directory with a manifest that lists the cases. Generation is deterministic and needs no network: the
/// shapes are procedural, plus the bundled meshes of data/.

#include <iosfwd>
#include <string>
#include <vector>

namespace cfl::tool {

/// One case: mesh A against itself (mesh_b empty) or A against B. Paths as written in the manifest.
struct SuiteCase {
  std::string name;
  std::string mesh_a;
  std::string mesh_b;  ///< Empty: A against itself.
  int line = 0;        ///< Where the manifest states it (1-based), for messages.
};

/// The manifest's file name inside a suite directory.
constexpr const char* kManifestName = "manifest.txt";

/// Writes every mesh of the suite and DIR/manifest.txt (DIR is created when missing; files are
/// overwritten). `huge` adds the 1.4M-triangle scan, which takes minutes to benchmark and is left out by
/// default. Prints one line per file to `log`. Throws cfl::Error naming the file that cannot be written, or
/// the bundled mesh that cannot be found.
void generateSuite(const std::string& dir, bool huge, std::ostream& log);

/// Parses a manifest: one case per line, "NAME MESH_A [MESH_B]", separated by spaces or tabs; '#' starts a
/// comment and blank lines are skipped. Names must be unique. Throws cfl::Error "PATH:LINE: reason" for a
/// malformed line, and "PATH: ..." when the file cannot be read or holds no case.
std::vector<SuiteCase> readManifest(const std::string& path);

/// `path` resolved against the manifest's directory `dir` unless absolute.
std::string resolveSuitePath(const std::string& dir, const std::string& path);

}  // namespace cfl::tool
