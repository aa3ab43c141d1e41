#pragma once
/// @file
/// The discrete Voronoi regions of a mesh: a voxel grid where every voxel holds its Closest Feature List
/// (CFL), the triangles that can be the closest triangle to some point of the voxel (Kawachi & Suzuki,
/// "Distance Computation between Non-convex Polyhedra at Short Range Based on Discrete Voronoi Regions",
/// section 3).

#include "cfl/mesh_model.h"
#include "cfl/voxel_grid.h"

#include <cstdint>
#include <functional>
#include <vector>

namespace cfl {

/// How to precompute a CflModel. Every field has a default that works.
struct BuildOptions {
  /// Voxels along the grid's longest axis. 0 picks one automatically (see automaticResolution).
  /// Cost grows with its cube: finer grids give shorter lists (faster queries) for more build time and memory.
  int resolution = 0;
  /// The grid covers the mesh's bounding box scaled by this factor about its center. Must be >= 1. Parts
  /// of the other mesh outside the grid are still answered exactly, through the two meshes' Bvhs, by node
  /// bounds that cost more than inside, where the grid's distance field prunes in O(1). The paper uses 2;
  /// 3 keeps a mesh half a diagonal away inside the grid: in `cfl bench` on the bunny that band went from
  /// 1.0x to 3.0x OBBRSS (CFL median 208.8 -> 77.4 us) for 1.6x the memory (5.4 -> 8.7 MB, same voxel
  /// size).
  double padding = 3.0;
  /// Topology culling (paper section 3.6, made provably conservative): triangle i leaves a voxel's list
  /// when, for every point of the voxel, i's closest point lies on an edge (shared vertex indices) that a
  /// triangle j also has, so j is at least as close, and j stays in the list, is missing from it (strictly
  /// beaten), or has itself left this way. Following such a chain from any closest triangle never gets
  /// farther and ends at a listed one; triangles that only witness each other in a loop all stay, and the
  /// result does not depend on list order. The paper's plane through the edge along the mean normal is not
  /// conservative for finite or concave triangles; these half-spaces are, on any mesh (open, non-manifold,
  /// unoriented), so it is on by default. On the bunny at resolution 30 it shortens the average list from
  /// 85.01 to 41.25 triangles, and the build is no slower (0.35-0.37 s against 0.37-0.39 s, 2 threads).
  bool topology_culling = true;
  /// Worker threads for the build; 0 means every hardware thread. The result does not depend on it.
  int threads = 0;
  /// Called from the calling thread with the fraction done, in [0, 1], a few hundred times per build.
  std::function<void(double)> progress;
};

/// Figures of a built model (paper Table 1).
struct BuildStatistics {
  int resolution = 0;                 ///< Voxels along the longest axis.
  std::int64_t voxel_count = 0;
  double average_list_length = 0;     ///< Mean CFL length over all voxels.
  std::int64_t longest_list = 0;
  std::int64_t distinct_lists = 0;    ///< Identical lists are stored once.
  std::int64_t memory_bytes = 0;      ///< Bytes of the model, mesh and Bvh included.
  double build_seconds = 0;           ///< Wall time of buildCflModel.
};

/// A mesh with its CFL voxels. Plain data; immutable once built, so any number of threads may query one
/// model at once. Built by buildCflModel or loaded from a file.
struct CflModel {
  MeshModel geometry;  ///< The mesh, its corners and its Bvh (frame M).
  VoxelGrid grid;      ///< Frame M.
  double padding = 3.0;
  bool topology_culling = false;

  /// CSR storage of the lists: voxel v's CFL is
  /// list_triangles[list_offsets[voxel_list[v]], list_offsets[voxel_list[v] + 1]).
  /// Triangle ids are indices into geometry.mesh.triangles. Within a list, entries are sorted by
  /// (list_entry_bounds, id), both increasing, so a query scans the nearest triangles first and stops at the
  /// first entry whose bound reaches its best distance.
  std::vector<std::uint32_t> voxel_list;
  std::vector<std::uint32_t> list_offsets;
  std::vector<std::int32_t> list_triangles;
  /// Parallel to list_triangles: a lower bound on the distance between the entry's triangle and the
  /// voxels that use the list, in units of entryBoundUnit(), rounded down and saturated at 255. One byte
  /// per entry; lists are shared only between voxels whose ids and bounds both agree.
  std::vector<std::uint8_t> list_entry_bounds;

  /// Per voxel, a lower bound on the distance from any point of the voxel to the mesh (0 where the mesh
  /// passes through the voxel).
  std::vector<double> voxel_lower_bound;
  /// Per grid corner, the distance from the corner to the mesh (rounded down). Distance to a set is
  /// 1-Lipschitz, so dist(p, mesh) >= corner_distance[c] - |p - corner c| for every point p.
  std::vector<double> corner_distance;

  BuildStatistics statistics;

  /// The CFL of voxel v as a [begin, end) range of triangle ids.
  const std::int32_t* listBegin(std::int64_t v) const { return list_triangles.data() + list_offsets[voxel_list[v]]; }
  const std::int32_t* listEnd(std::int64_t v) const { return list_triangles.data() + list_offsets[voxel_list[v] + 1]; }
  /// The unit of list_entry_bounds: 1/32 of a voxel edge, so bounds up to about 8 voxel edges are kept.
  double entryBoundUnit() const { return grid.voxel_size / 32; }
  /// The entry bounds of voxel v's CFL, parallel to [listBegin(v), listEnd(v)).
  const std::uint8_t* listBoundsBegin(std::int64_t v) const { return list_entry_bounds.data() + list_offsets[voxel_list[v]]; }
};

/// The resolution used when BuildOptions::resolution is 0: voxels of about 1.25 mean triangle edge lengths,
/// clamped to [8, 32 * padding] (the upper end itself kept within [64, 96]) so that build time stays in
/// seconds while the voxel size near the mesh does not depend on the padding. Finer voxels make short-range
/// queries faster and builds slower; the measurements behind the rule are in cfl_builder.cpp.
int automaticResolution(const TriangleMesh& mesh, double padding);

/// Precomputes the CFL voxels of `mesh`.
///
/// Every list is conservative: for every point p of a voxel, the list holds a triangle at distance
/// dist(p, mesh) from p. A triangle i is left out of voxel V only when some triangle k satisfies
/// dmax(V, k) < dmin(V, i), where dmin is a lower bound on the voxel-triangle distance and dmax the largest
/// corner-triangle distance (the farthest point of V from triangle k, distance being convex).
///
/// Throws cfl::Error for an invalid mesh (see validateMesh), resolution < 0, padding < 1 or not finite, or a
/// grid whose lists would not fit in memory (the message says how many voxels and bytes it would need).
/// Time: roughly O(voxels * local triangles), spread over BuildOptions::threads.
CflModel buildCflModel(TriangleMesh mesh, const BuildOptions& options = {});

}  // namespace cfl
