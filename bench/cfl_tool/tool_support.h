#pragma once
/// @file
/// Pieces of the `cfl` tool shared by its subcommands: finding bundled data, progress output, loading a
/// mesh or a CFL file, printing statistics.

#include "cfl/cfl_model.h"

#include <functional>
#include <iosfwd>
#include <string>
#include <vector>

namespace cfl::tool {

/// The places searched for a bundled data file, in order: $CFL_DATA_DIR, the source tree's data/ (compiled
/// in), <executable>/../share/cfl/data (an installed, relocated tree), and the install prefix's
/// share/cfl/data (compiled in).
std::vector<std::string> dataDirectories();

/// The path of bundled data file `name` (e.g. "bunny.obj"); cfl::Error listing every directory searched
/// when none has it.
std::string findDataFile(const std::string& name);

/// Build progress on a stream: on a terminal, one bar redrawn in place; otherwise one plain line per 10%.
class ProgressReporter {
 public:
  ProgressReporter(std::ostream& out, std::string label, bool terminal);
  void update(double fraction);
  /// Ends the bar (or the lines) with the elapsed time.
  void finish(double seconds);
  /// A callback for BuildOptions::progress that forwards to update(); `this` must outlive the build.
  std::function<void(double)> callback();

 private:
  std::ostream& out_;
  std::string label_;
  bool terminal_;
  int last_shown_ = -1;
};

/// Whether standard error is a terminal (decides the progress style).
bool stderrIsTerminal();

/// Whether `path` names a CFL model file (extension ".cfl", any case).
bool isCflFile(const std::string& path);

/// Reads a mesh file through cfl::loadMesh, or the mesh stored in a .cfl file.
TriangleMesh readMeshArgument(const std::string& path);

/// A CFL model for `path`: loaded when it is a .cfl file (options ignored), built from the mesh otherwise,
/// with progress on `progress_out` (standard error in the tool).
CflModel obtainCflModel(const std::string& path, BuildOptions options, std::ostream& progress_out);

/// Prints a model's statistics (voxels, lists, memory, build time), one "name: value" per line.
void printStatistics(const CflModel& model, std::ostream& out);

/// printf-style formatting into a std::string.
std::string format(const char* fmt, ...) __attribute__((format(printf, 1, 2)));

}  // namespace cfl::tool
