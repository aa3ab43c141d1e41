#pragma once
/// @file
/// The adaptive discrete Voronoi regions of a mesh: a shallow tree of cubic cells, each leaf holding its
/// Closest Feature List (CFL), the triangles that can be closest to some point of the leaf.
///
/// Layout (after NanoVDB's: plain arrays, indices instead of pointers, read-only once built): a root grid of
/// root_dims[0] x root_dims[1] x root_dims[2] cubic cells of edge root_size from `origin`; each cell is either
/// a leaf or split into 2 x 2 x 2 children of half its edge, down to at most `max_depth` levels below the
/// root. Cells are refined where their lists would be long and kept coarse where lists are short (far from
/// the mesh, over large flat triangles), so that memory grows with the surface, not with the bounding box.
/// A uniform grid is the special case max_depth == 0 (every root cell a leaf), which BuildOptions::resolution
/// asks for.

#include "cfl/error.h"
#include "cfl/mesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace cfl {

/// A leaf found by point location: its index into the leaf arrays, its box and its depth.
struct RegionCell {
  std::uint32_t leaf = 0;
  Eigen::Vector3d min_corner = Eigen::Vector3d::Zero();  ///< Frame M.
  double size = 0;  ///< Edge length.
  int depth = 0;    ///< 0 for a root cell.
};

/// All fields are plain data, frame M (the mesh's), lengths in the mesh's units. Immutable once built:
/// any number of threads may read one tree at once.
struct RegionTree {
  /// nodes[n] with this bit set is a leaf whose index is the other bits; otherwise it is the index of the
  /// first of n's eight children, stored consecutively, child c covering the octant with x-bit c & 1, y-bit
  /// (c >> 1) & 1, z-bit c >> 2 (set: the upper half).
  static constexpr std::uint32_t kLeafBit = 0x80000000u;
  /// leaf_list value of a leaf that stores no list: its list would be longer than a walk of the mesh's Bvh
  /// costs (far above a flat part, or among many tiny triangles), so queries test what falls in it against
  /// the Bvh instead. Only adaptive regions have such leaves.
  static constexpr std::uint32_t kNoList = 0xffffffffu;
  /// The deepest level a leaf may have below the root (forEachLeafInBox's fixed stack is sized for it).
  static constexpr int kMaxDepth = 24;

  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  ///< Min corner of the root grid.
  double root_size = 0;                              ///< Edge of a root cell.
  std::array<int, 3> root_dims{0, 0, 0};
  int max_depth = 0;  ///< Deepest level any leaf has (0: a uniform grid of root cells).

  /// nodes[0, rootCount()) are the root cells, root cell (i, j, k) at i + root_dims[0] (j + root_dims[1] k);
  /// their descendants follow.
  std::vector<std::uint32_t> nodes;

  /// Per leaf. leaf_list: index of its CFL (lists are shared between leaves whose ids, entry bounds and
  /// depth agree), or kNoList. leaf_lower_bound: a lower bound on the distance from any point of the leaf to the mesh
  /// (0 where the mesh passes through it). leaf_corner_distance: the distance from each of its eight
  /// corners to the mesh, corner c at min_corner + size (c & 1, (c >> 1) & 1, c >> 2), in units of
  /// cornerDistanceUnit(size), rounded down, saturated at kCornerDistanceSaturated: read it through
  /// cornerDistanceLower and cornerDistanceUpper. Distance to a set is 1-Lipschitz, so dist(p, mesh) >=
  /// corner distance - |p - corner| for every p. Sixteen bits per corner instead of a float: with a unit of
  /// a small fraction of the leaf's edge they lose nothing that matters to a bound, and they were the
  /// largest per-leaf array.
  std::vector<std::uint32_t> leaf_list;
  std::vector<float> leaf_lower_bound;
  std::vector<std::array<std::uint16_t, 8>> leaf_corner_distance;
  /// The unit of leaf_corner_distance as a fraction of a leaf's edge: a power of two in
  /// [kFinestCornerDistanceUnit, 1], the finest that keeps the farthest corner (in edges of its leaf)
  /// below saturation, so that multiplying by it is exact.
  double corner_distance_unit = kFinestCornerDistanceUnit;
  static constexpr std::uint16_t kCornerDistanceSaturated = 0xffff;
  static constexpr double kFinestCornerDistanceUnit = 1.0 / 65536;

  /// CSR storage of the lists: list l is entries [list_offsets[l], list_offsets[l + 1]), bounds in
  /// list_entry_bounds at those indices. Within a list, entries are sorted by (list_entry_bounds, triangle
  /// id), both increasing, so a query scans the nearest triangles first and stops at the first entry whose
  /// bound reaches its best distance. Read the ids with listTriangle / forEachListTriangle; add lists with
  /// appendList.
  std::vector<std::uint32_t> list_offsets;
  /// The ids, 16 bits each: list l starts at listIdsBegin(l) = list_offsets[l] + 2 l with two slots holding
  /// its base (a 32-bit signed integer, low half first), then one slot per entry. With base >= 0, entry n
  /// is triangle base + slot (the list's ids span less than 65536: every list of a mesh below 65536
  /// triangles, nearly every one of a larger mesh's, whose lists hold the triangles near one cell). With
  /// base < 0 the list is "wide": the slot holds the id's low 16 bits and list_high_ids[~base + n] its high
  /// bits. The base sits next to the ids, on their cache line. Two bytes per entry instead of four: the
  /// lists are most of a model.
  std::vector<std::uint16_t> list_entry_ids;
  std::vector<std::uint16_t> list_high_ids;
  /// Parallel to the entries: a lower bound on the distance between the entry's triangle and the leaves
  /// that use the list, in units of entryBoundUnit(depth) of those leaves, rounded down, saturated at 255.
  std::vector<std::uint8_t> list_entry_bounds;

  std::int64_t rootCount() const { return std::int64_t(root_dims[0]) * root_dims[1] * root_dims[2]; }
  std::int64_t leafCount() const { return std::int64_t(leaf_list.size()); }
  double cellSize(int depth) const { return root_size / double(std::int64_t(1) << depth); }
  /// The unit of list_entry_bounds at a depth: 1/32 of the cell edge, so bounds up to 8 edges are kept.
  double entryBoundUnit(int depth) const { return cellSize(depth) / 32; }
  /// The unit of the corner distances of a leaf of edge `size` (cellSize of its depth).
  double cornerDistanceUnit(double size) const { return size * corner_distance_unit; }
  /// A stored corner distance as a lower bound on the corner's distance to the mesh (`unit`:
  /// cornerDistanceUnit of its leaf).
  static double cornerDistanceLower(std::uint16_t stored, double unit) { return double(stored) * unit; }
  /// A stored corner distance as an upper bound on the corner's distance to the mesh, up to the float
  /// rounding of the build's distances (inflate it by a relative 1e-6 before relying on it); infinite when
  /// saturated.
  static double cornerDistanceUpper(std::uint16_t stored, double unit) {
    return stored == kCornerDistanceSaturated ? std::numeric_limits<double>::infinity() : double(stored + 1) * unit;
  }
  /// The stored form of a corner distance `distance` (>= 0; NaN stores 0): the most units whose
  /// cornerDistanceLower does not exceed it, saturated.
  static std::uint16_t encodeCornerDistance(double distance, double unit) {
    if (!(distance >= 0)) return 0;
    const double units = distance / unit;
    double stored = units < double(kCornerDistanceSaturated) ? std::floor(units) : double(kCornerDistanceSaturated);
    while (stored > 0 && stored * unit > distance) stored -= 1;  // the division may have rounded up
    return static_cast<std::uint16_t>(stored);
  }
  /// The box of the root grid.
  Aabb bounds() const {
    Aabb box;
    box.min = origin;
    box.max = origin + root_size * Eigen::Vector3d(root_dims[0], root_dims[1], root_dims[2]);
    return box;
  }
  bool hasList(std::uint32_t leaf) const { return leaf_list[leaf] != kNoList; }
  std::size_t listCount() const { return list_offsets.empty() ? 0 : list_offsets.size() - 1; }
  std::uint32_t listLength(std::uint32_t list) const { return list_offsets[list + 1] - list_offsets[list]; }
  /// Index in list_entry_ids of the list's base (its entries follow it).
  std::size_t listIdsBegin(std::uint32_t list) const { return std::size_t(list_offsets[list]) + 2 * std::size_t(list); }
  std::int32_t listBase(std::uint32_t list) const {
    const std::uint16_t* slots = list_entry_ids.data() + listIdsBegin(list);
    return std::int32_t(std::uint32_t(slots[0]) | std::uint32_t(slots[1]) << 16);
  }
  /// Entry n of list `list`: a triangle id.
  std::int32_t listTriangle(std::uint32_t list, std::uint32_t n) const {
    const std::int32_t base = listBase(list);
    const std::uint16_t low = list_entry_ids[listIdsBegin(list) + 2 + n];
    if (base >= 0) return base + std::int32_t(low);
    return std::int32_t(std::uint32_t(low) | std::uint32_t(list_high_ids[std::uint32_t(~base) + n]) << 16);
  }
  /// Calls visit(n, id) for the first `count` entries of list `list` (count <= listLength(list)), in order.
  template <class Visit>
  void forEachListTriangle(std::uint32_t list, std::ptrdiff_t count, Visit&& visit) const {
    const std::uint16_t* slots = list_entry_ids.data() + listIdsBegin(list);
    const std::int32_t base = std::int32_t(std::uint32_t(slots[0]) | std::uint32_t(slots[1]) << 16);
    const std::uint16_t* low = slots + 2;
    if (base >= 0) {
      for (std::ptrdiff_t n = 0; n < count; ++n) visit(n, base + std::int32_t(low[n]));
    } else {
      const std::uint16_t* high = list_high_ids.data() + std::uint32_t(~base);
      for (std::ptrdiff_t n = 0; n < count; ++n)
        visit(n, std::int32_t(std::uint32_t(low[n]) | std::uint32_t(high[n]) << 16));
    }
  }
  /// Appends a list of `length` triangle ids (>= 0) with their entry bounds, already sorted by (bound, id);
  /// returns its index. Throws cfl::Error past 2^31 wide entries (tens of gigabytes of lists).
  std::uint32_t appendList(const std::int32_t* ids, const std::uint8_t* bounds, std::uint32_t length) {
    if (list_offsets.empty()) list_offsets.push_back(0);
    std::int32_t lowest = length > 0 ? ids[0] : 0, highest = lowest;
    for (std::uint32_t n = 1; n < length; ++n) lowest = std::min(lowest, ids[n]), highest = std::max(highest, ids[n]);
    const bool narrow = std::int64_t(highest) - lowest < 65536;
    if (!narrow && list_high_ids.size() + length > std::size_t(std::numeric_limits<std::int32_t>::max())) {
      throw Error("the regions' lists hold more wide entries than a RegionTree indexes");
    }
    const std::uint32_t base = narrow ? std::uint32_t(lowest) : ~std::uint32_t(list_high_ids.size());
    list_entry_ids.push_back(std::uint16_t(base & 0xffffu));
    list_entry_ids.push_back(std::uint16_t(base >> 16));
    for (std::uint32_t n = 0; n < length; ++n) {
      const std::uint32_t id = std::uint32_t(ids[n]);
      list_entry_ids.push_back(std::uint16_t(narrow ? id - base : id & 0xffffu));
      if (!narrow) list_high_ids.push_back(std::uint16_t(id >> 16));
    }
    list_entry_bounds.insert(list_entry_bounds.end(), bounds, bounds + length);
    list_offsets.push_back(std::uint32_t(list_entry_bounds.size()));
    return std::uint32_t(list_offsets.size() - 2);
  }
  /// Every list's triangle ids, list after list, indexed as list_entry_bounds.
  std::vector<std::int32_t> listTriangles() const {
    std::vector<std::int32_t> ids;
    ids.reserve(list_entry_bounds.size());
    for (std::uint32_t list = 0; list < listCount(); ++list) {
      forEachListTriangle(list, listLength(list), [&](std::ptrdiff_t, std::int32_t id) { ids.push_back(id); });
    }
    return ids;
  }
  /// The CFL of a leaf that has one (hasList): its length, its ids and its entry bounds.
  std::uint32_t leafListLength(std::uint32_t leaf) const { return listLength(leaf_list[leaf]); }
  std::int32_t leafListTriangle(std::uint32_t leaf, std::uint32_t n) const { return listTriangle(leaf_list[leaf], n); }
  const std::uint8_t* listBoundsBegin(std::uint32_t leaf) const {
    return list_entry_bounds.data() + list_offsets[leaf_list[leaf]];
  }

  /// The leaf holding p (clamped into the root grid; a point on a face may get either side). O(depth): one
  /// array read per level.
  RegionCell locate(const Eigen::Vector3d& p) const {
    // Fixed point, kFraction bits per root cell: the octant at each level is one bit of each coordinate, so
    // the descent is shifts and masks and one array read per level.
    constexpr int kFraction = 24;
    constexpr double kScale = double(1 << kFraction);
    const Eigen::Vector3d q = (p - origin) * (kScale / root_size);
    std::int64_t fixed[3];
    for (int axis = 0; axis < 3; ++axis) {
      const double top = double(root_dims[axis]) * kScale - 1;
      const double clamped = q[axis] >= 0 ? (q[axis] < top ? q[axis] : top) : 0.0;  // NaN goes to 0
      fixed[axis] = static_cast<std::int64_t>(clamped);
    }
    std::uint32_t node = std::uint32_t(
        (fixed[0] >> kFraction) +
        std::int64_t(root_dims[0]) * ((fixed[1] >> kFraction) + std::int64_t(root_dims[1]) * (fixed[2] >> kFraction)));
    int depth = 0;
    std::uint32_t value = nodes[node];
    while (!(value & kLeafBit) && depth < kFraction) {
      const int shift = kFraction - 1 - depth;
      const std::uint32_t octant = std::uint32_t((fixed[0] >> shift) & 1) |
                                   std::uint32_t((fixed[1] >> shift) & 1) << 1 |
                                   std::uint32_t((fixed[2] >> shift) & 1) << 2;
      value = nodes[value + octant];
      ++depth;
    }
    RegionCell cell;
    cell.leaf = value & ~kLeafBit;
    cell.depth = depth;
    const int drop = kFraction - depth;
    cell.size = root_size / double(std::int64_t(1) << depth);
    cell.min_corner = origin + (root_size / kScale) * Eigen::Vector3d(double((fixed[0] >> drop) << drop),
                                                                       double((fixed[1] >> drop) << drop),
                                                                       double((fixed[2] >> drop) << drop));
    return cell;
  }

  /// Calls visit(const RegionCell&) for every leaf whose closed box meets the closed box [lo, hi] (frame M;
  /// clamped into the root grid) until visit returns false. Returns false when it was stopped that way.
  /// Allocation-free.
  template <class Visit>
  bool forEachLeafInBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, Visit&& visit) const {
    Eigen::Vector3d qlo = (lo - origin) / root_size, qhi = (hi - origin) / root_size;
    int first[3], last[3];
    for (int axis = 0; axis < 3; ++axis) {
      const double top = root_dims[axis];
      qlo[axis] = qlo[axis] >= 0 ? (qlo[axis] < top ? qlo[axis] : top) : 0.0;  // NaN goes to 0
      qhi[axis] = qhi[axis] >= 0 ? (qhi[axis] < top ? qhi[axis] : top) : 0.0;
      first[axis] = qlo[axis] < top ? int(qlo[axis]) : root_dims[axis] - 1;
      last[axis] = qhi[axis] < top ? int(qhi[axis]) : root_dims[axis] - 1;
    }
    struct Pending {
      std::uint32_t node;
      int depth;
      double x, y, z;  // lower corner in root-cell units
    };
    Pending stack[8 * kMaxDepth];  // at most 7 pending siblings per level
    for (int k = first[2]; k <= last[2]; ++k) {
      for (int j = first[1]; j <= last[1]; ++j) {
        for (int i = first[0]; i <= last[0]; ++i) {
          int top = 0;
          stack[top++] = {std::uint32_t(i + std::int64_t(root_dims[0]) * (j + std::int64_t(root_dims[1]) * k)), 0,
                          double(i), double(j), double(k)};
          while (top > 0) {
            const Pending cell = stack[--top];
            const std::uint32_t value = nodes[cell.node];
            const double size = 1.0 / double(std::int64_t(1) << cell.depth);
            if (value & kLeafBit) {
              RegionCell found;
              found.leaf = value & ~kLeafBit;
              found.min_corner = origin + root_size * Eigen::Vector3d(cell.x, cell.y, cell.z);
              found.size = root_size * size;
              found.depth = cell.depth;
              if (!visit(static_cast<const RegionCell&>(found))) return false;
              continue;
            }
            const double half = 0.5 * size;
            for (int octant = 7; octant >= 0; --octant) {
              const double x = cell.x + half * (octant & 1), y = cell.y + half * ((octant >> 1) & 1),
                           z = cell.z + half * (octant >> 2);
              if (x > qhi[0] || x + half < qlo[0] || y > qhi[1] || y + half < qlo[1] || z > qhi[2] ||
                  z + half < qlo[2]) {
                continue;
              }
              stack[top++] = {value + std::uint32_t(octant), cell.depth + 1, x, y, z};
            }
          }
        }
      }
    }
    return true;
  }
};

}  // namespace cfl
