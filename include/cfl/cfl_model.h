#pragma once
/// @file
/// A mesh with its discrete Voronoi regions (region_tree.h): cells whose Closest Feature Lists (CFL) hold
/// the triangles that can be the closest triangle to some point of the cell (Kawachi & Suzuki, "Distance
/// Computation between Non-convex Polyhedra at Short Range Based on Discrete Voronoi Regions", section 3),
/// and how to build them.

#include "cfl/mesh_model.h"
#include "cfl/mesh_sign.h"
#include "cfl/region_tree.h"

#include <cstdint>
#include <functional>
#include <vector>

namespace cfl {

/// How to precompute a CflModel. Every field has a default that works.
struct BuildOptions {
  /// 0 (the default): adaptive regions, cells refined where their lists are long and kept coarse where
  /// they are short, sized automatically. N > 0: the paper's uniform grid, N cells along the longest axis of
  /// the padded box and no refinement (`cfl paper` uses it to reproduce the paper's mode).
  int resolution = 0;
  /// The regions cover the mesh's bounding box grown on every side by (padding - 1) / 2 times its longest
  /// extent, the same margin on every axis, so that a flat or long part still has room around it in every
  /// direction. Must be >= 1. Parts of the other mesh outside are still answered exactly, through the two
  /// meshes' Bvhs, by node bounds that cost more than inside, where the regions' distance field prunes in
  /// O(1). Outside cells are coarse, so a large padding costs little memory.
  double padding = 3.0;
  /// Topology culling (paper section 3.6, made provably conservative): triangle i leaves a cell's list
  /// when, for every point of the cell, i's closest point lies on an edge (shared vertex indices) that a
  /// triangle j also has, so j is at least as close, and j stays in the list, is missing from it (strictly
  /// beaten), or has itself left this way. Following such a chain from any closest triangle never gets
  /// farther and ends at a listed one; triangles that only witness each other in a loop all stay, and the
  /// result does not depend on list order. The paper's plane through the edge along the mean normal is not
  /// conservative for finite or concave triangles; these half-spaces are, on any mesh (open, non-manifold,
  /// unoriented), so it is on by default.
  bool topology_culling = true;
  /// Worker threads for the build; 0 means every hardware thread. The result does not depend on it.
  int threads = 0;
  /// Memory budget of the regions in bytes (the mesh and its Bvh come on top); 0 means the smaller of half
  /// of this machine's physical memory and 32 MiB + 2 KiB per triangle. The root cells are always built: a
  /// limit below what they need at the least (about 48 bytes each) is refused with a cfl::Error, for
  /// uniform and adaptive builds alike. Past that, an adaptive build stops refining once its leaves and
  /// lists reach the budget (its lists get longer, never wrong) and says so in BuildStatistics::coarsened;
  /// the root cells' own lists may take the model somewhat past it.
  std::int64_t memory_limit = 0;
  /// Called from the calling thread with the fraction done, in [0, 1], a few hundred times per build.
  std::function<void(double)> progress;
};

/// Figures of a built model (paper Table 1).
struct BuildStatistics {
  int resolution = 0;                 ///< Cells of the finest level along the longest axis of the regions.
  std::int64_t voxel_count = 0;       ///< Leaves (the cells that hold lists).
  std::vector<std::int64_t> leaves_per_depth;  ///< Leaves at each depth, root cells first.
  std::int64_t leaves_without_list = 0;        ///< Leaves that store no list (RegionTree::kNoList).
  double average_list_length = 0;     ///< Mean CFL length over the leaves that store one.
  std::int64_t longest_list = 0;
  std::int64_t distinct_lists = 0;    ///< Identical lists are stored once.
  std::int64_t memory_bytes = 0;      ///< Bytes the model's arrays hold (capacity), mesh, Bvh and MeshSign included.
  bool coarsened = false;             ///< The build stopped refining at BuildOptions::memory_limit.
  double build_seconds = 0;           ///< Wall time of buildCflModel.
};

/// A mesh with its adaptive discrete Voronoi regions. Plain data; immutable once built, so any number of
/// threads may query one model at once. Built by buildCflModel or loaded from a file.
struct CflModel {
  MeshModel geometry;   ///< The mesh, its corners and its Bvh (frame M).
  RegionTree regions;   ///< Frame M.
  /// Whether the mesh is closed, and what signing its distances needs (mesh_sign.h). Derived from the mesh
  /// by analyzeMeshSign when the model is built or loaded; not stored in files.
  MeshSign sign;
  double padding = 3.0;
  bool topology_culling = false;
  BuildStatistics statistics;
};

/// Precomputes the discrete Voronoi regions of `mesh`.
///
/// Every list is conservative: for every point p of a leaf, the list holds a triangle at distance
/// dist(p, mesh) from p. A triangle i is left out of cell V only when some triangle k satisfies
/// dmax(V, k) < dmin(V, i), where dmin is a lower bound on the cell-triangle distance and dmax the largest
/// corner-triangle distance (the farthest point of V from triangle k, distance being convex), when a cone
/// test shows another triangle strictly closer everywhere in V, or by topology culling.
///
/// Adaptive (resolution 0): a root grid of 16 cells along the padded box's longest axis; a cell splits in
/// eight while its list holds more than 8 triangles, it is larger than 2 mean edges of those triangles,
/// and it is larger than half its distance from the mesh. A leaf whose list is still longer than 256
/// triangles within 4 of its edges from the mesh, or 64 farther out, stores none (RegionTree::kNoList);
/// queries use the Bvh there. The regions (nodes, leaf arrays and lists) are kept within 1 MiB plus 688 bytes
/// per triangle, which meshes with much empty space around thin parts (a long pipe) reach first: past it,
/// the leaves of one cell share a single list, the union of theirs with entry bounds taken from the whole
/// cell, starting with the cells farthest from the mesh, and if that is not enough the lists farthest from
/// the mesh are dropped. The lists of the leaves nearest the surface, which short-range queries read, are
/// the last to change.
///
/// Throws cfl::Error for an invalid mesh (see validateMesh), resolution < 0, padding < 1 or not finite, a
/// negative memory_limit, or a uniform grid whose cells alone would exceed the memory limit (the message
/// says how many cells and bytes it would need). Time: roughly O(cells * local triangles), spread over
/// BuildOptions::threads with work stealing (oneTBB).
CflModel buildCflModel(TriangleMesh mesh, const BuildOptions& options = {});

}  // namespace cfl
