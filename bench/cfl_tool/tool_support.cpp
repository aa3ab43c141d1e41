#include "tool_support.h"

#include "cfl/cfl_file.h"
#include "cfl/error.h"
#include "cfl/mesh_io.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <ostream>

#ifndef CFL_DATA_DIR
#error "CFL_DATA_DIR must be defined by the build"
#endif
#ifndef CFL_INSTALL_DATA_DIR
#error "CFL_INSTALL_DATA_DIR must be defined by the build"
#endif

namespace cfl::tool {

std::vector<std::string> dataDirectories() {
  std::vector<std::string> dirs;
  if (const char* env = std::getenv("CFL_DATA_DIR"); env != nullptr && *env != '\0') dirs.push_back(env);
  dirs.push_back(CFL_DATA_DIR);
  char exe[4096];
  const ssize_t n = ::readlink("/proc/self/exe", exe, sizeof exe - 1);
  if (n > 0) {
    std::string path(exe, std::size_t(n));
    const auto slash = path.rfind('/');
    if (slash != std::string::npos) dirs.push_back(path.substr(0, slash) + "/../share/cfl/data");
  }
  dirs.push_back(CFL_INSTALL_DATA_DIR);
  return dirs;
}

std::string findDataFile(const std::string& name) {
  std::string searched;
  for (const std::string& dir : dataDirectories()) {
    const std::string path = dir + "/" + name;
    if (std::ifstream(path).good()) return path;
    searched += "\n  " + dir;
  }
  throw Error("bundled data file '" + name + "' not found; searched:" + searched +
              "\nset CFL_DATA_DIR to the directory holding it");
}

ProgressReporter::ProgressReporter(std::ostream& out, std::string label, bool terminal)
    : out_(out), label_(std::move(label)), terminal_(terminal) {}

void ProgressReporter::update(double fraction) {
  const int percent = std::clamp(int(fraction * 100.0), 0, 100);
  if (terminal_) {
    if (percent == last_shown_) return;
    constexpr int kWidth = 30;
    const int filled = percent * kWidth / 100;
    out_ << '\r' << label_ << " [" << std::string(std::size_t(filled), '#')
         << std::string(std::size_t(kWidth - filled), '.') << "] " << format("%3d%%", percent) << std::flush;
  } else {
    // Plain lines, one per 10%, so logs stay short.
    const int step = percent / 10 * 10;
    if (step <= last_shown_) return;
    out_ << label_ << ": " << step << "%\n" << std::flush;
    last_shown_ = step;
    return;
  }
  last_shown_ = percent;
}

void ProgressReporter::finish(double seconds) {
  if (terminal_) {
    update(1.0);
    out_ << format(" %.3f s\n", seconds) << std::flush;
  } else {
    out_ << label_ << format(": done in %.3f s\n", seconds) << std::flush;
  }
}

std::function<void(double)> ProgressReporter::callback() {
  return [this](double fraction) { update(fraction); };
}

bool stderrIsTerminal() { return ::isatty(STDERR_FILENO) == 1; }

bool isCflFile(const std::string& path) {
  if (path.size() < 4) return false;
  std::string ext = path.substr(path.size() - 4);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext == ".cfl";
}

TriangleMesh readMeshArgument(const std::string& path) {
  if (isCflFile(path)) return loadCflModel(path).geometry.mesh;
  return loadMesh(path);
}

CflModel obtainCflModel(const std::string& path, BuildOptions options, std::ostream& progress_out) {
  if (isCflFile(path)) return loadCflModel(path);
  TriangleMesh mesh = loadMesh(path);
  ProgressReporter progress(progress_out, "building the Voronoi regions of " + path, stderrIsTerminal());
  options.progress = progress.callback();
  const auto start = std::chrono::steady_clock::now();
  CflModel model = buildCflModel(std::move(mesh), options);
  progress.finish(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return model;
}

void printStatistics(const CflModel& model, std::ostream& out) {
  const BuildStatistics& s = model.statistics;
  const Aabb& b = model.geometry.bounds;
  out << format("triangles:           %zu\n", model.geometry.mesh.triangles.size());
  out << format("vertices:            %zu\n", model.geometry.mesh.vertices.size());
  out << format("bounding box:        [%g, %g, %g] - [%g, %g, %g] (diagonal %g)\n", b.min.x(), b.min.y(),
                b.min.z(), b.max.x(), b.max.y(), b.max.z(), b.diagonal());
  const RegionTree& r = model.regions;
  const std::size_t triangles = std::max<std::size_t>(model.geometry.mesh.triangles.size(), 1);
  out << format("regions:             %s, root grid %d x %d x %d of edge %g, %d levels below it, padding %g\n",
                r.max_depth > 0 ? "adaptive" : "uniform", r.root_dims[0], r.root_dims[1], r.root_dims[2], r.root_size,
                r.max_depth, model.padding);
  out << format("finest cell edge:    %g (%d along the longest axis)\n", r.cellSize(r.max_depth), s.resolution);
  out << format("leaves:              %lld\n", static_cast<long long>(s.voxel_count));
  for (std::size_t depth = 0; depth < s.leaves_per_depth.size(); ++depth) {
    out << format("  depth %2zu:          %lld of edge %g\n", depth, static_cast<long long>(s.leaves_per_depth[depth]),
                  r.cellSize(int(depth)));
  }
  out << format("without a list:      %lld (queries use the Bvh there)\n", static_cast<long long>(s.leaves_without_list));
  out << format("average CFL length:  %.3f\n", s.average_list_length);
  out << format("longest CFL:         %lld\n", static_cast<long long>(s.longest_list));
  out << format("distinct lists:      %lld\n", static_cast<long long>(s.distinct_lists));
  out << format("memory:              %.2f MB (%.1f bytes per triangle, %.1f per leaf)%s\n",
                double(s.memory_bytes) / (1 << 20), double(s.memory_bytes) / double(triangles),
                s.voxel_count > 0 ? double(s.memory_bytes) / double(s.voxel_count) : 0.0,
                s.coarsened ? "; refinement stopped at the memory limit" : "");
  // Where the bytes go: each array's capacity, per triangle.
  const MeshModel& g = model.geometry;
  auto perTriangle = [&](std::size_t bytes) { return double(bytes) / double(triangles); };
  auto bytesOf = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
  out << format("  mesh:              %.1f B/triangle (vertices %.1f, triangles %.1f)\n",
                perTriangle(bytesOf(g.mesh.vertices) + bytesOf(g.mesh.triangles)), perTriangle(bytesOf(g.mesh.vertices)),
                perTriangle(bytesOf(g.mesh.triangles)));
  out << format("  triangle data:     %.1f B/triangle (corners %.1f and their index %.1f, spheres %.1f, planes %.1f; "
                "spheres and planes in leaf order %.1f; spines %.1f)\n",
                perTriangle(bytesOf(g.corners.in_leaf_order) + bytesOf(g.corners.leaf_position) + bytesOf(g.spheres) +
                            bytesOf(g.planes) + bytesOf(g.leaf_spheres) + bytesOf(g.leaf_planes) + bytesOf(g.spines)),
                perTriangle(bytesOf(g.corners.in_leaf_order)), perTriangle(bytesOf(g.corners.leaf_position)),
                perTriangle(bytesOf(g.spheres)), perTriangle(bytesOf(g.planes)),
                perTriangle(bytesOf(g.leaf_spheres) + bytesOf(g.leaf_planes)), perTriangle(bytesOf(g.spines)));
  out << format("  Bvh:               %.1f B/triangle (%zu nodes of %zu B, triangle ids %.1f, compact nodes %.1f, "
                "spine radii %.1f)\n",
                perTriangle(bytesOf(g.bvh.nodes) + bytesOf(g.bvh.triangle_ids) + bytesOf(g.compact_nodes) +
                            bytesOf(g.node_spine_radii)),
                g.bvh.nodes.size(), sizeof(BvhNode), perTriangle(bytesOf(g.bvh.triangle_ids)),
                perTriangle(bytesOf(g.compact_nodes)), perTriangle(bytesOf(g.node_spine_radii)));
  out << format("  region nodes:      %.1f B/triangle (%zu nodes)\n", perTriangle(bytesOf(r.nodes)), r.nodes.size());
  out << format("  leaf arrays:       %.1f B/triangle (list ids %.1f, lower bounds %.1f, corner distances %.1f)\n",
                perTriangle(bytesOf(r.leaf_list) + bytesOf(r.leaf_lower_bound) + bytesOf(r.leaf_corner_distance)),
                perTriangle(bytesOf(r.leaf_list)), perTriangle(bytesOf(r.leaf_lower_bound)),
                perTriangle(bytesOf(r.leaf_corner_distance)));
  out << format("  lists:             %.1f B/triangle (%zu entries: ids and bases %.1f, wide ids' high bits %.1f, bounds %.1f; "
                "offsets %.1f)\n",
                perTriangle(bytesOf(r.list_entry_ids) + bytesOf(r.list_high_ids) + bytesOf(r.list_entry_bounds) +
                            bytesOf(r.list_offsets)),
                r.list_entry_bounds.size(), perTriangle(bytesOf(r.list_entry_ids)), perTriangle(bytesOf(r.list_high_ids)),
                perTriangle(bytesOf(r.list_entry_bounds)), perTriangle(bytesOf(r.list_offsets)));
  out << format("build time:          %.3f s\n", s.build_seconds);
  out << format("topology culling:    %s\n", model.topology_culling ? "on" : "off");
  out << format("closed:              %s\n", model.sign.closure.closed ? "yes" : ("no (" + model.sign.closure.reason + ")").c_str());
}

std::string format(const char* fmt, ...) {
  va_list args;
  va_start(args, fmt);
  va_list copy;
  va_copy(copy, args);
  const int n = std::vsnprintf(nullptr, 0, fmt, copy);
  va_end(copy);
  std::string out(std::size_t(std::max(n, 0)), '\0');
  if (n > 0) std::vsnprintf(out.data(), out.size() + 1, fmt, args);
  va_end(args);
  return out;
}

}  // namespace cfl::tool
