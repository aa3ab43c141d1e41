#include "cfl/cfl_model.h"

#include "cfl/error.h"
#include "cfl/triangle_distance.h"
#include "detail/box_triangle_bound.h"
#include "detail/nearest_triangle.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <thread>
#include <unordered_map>
#include <unistd.h>

namespace cfl {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

int workerCount(int requested) {
  if (requested > 0) return requested;
  const unsigned hardware = std::thread::hardware_concurrency();
  return hardware == 0 ? 1 : static_cast<int>(hardware);
}

// Runs task(item, worker) for item in [0, count) on `threads` workers numbered from 0, the calling thread
// being worker 0, pulling items from a shared counter so that uneven rows balance out. Only the calling
// thread reports progress, between its own items, so the callback never runs elsewhere; with one thread
// nothing is spawned.
template <typename Task>
void parallelFor(std::int64_t count, int threads, const std::function<void(double)>& progress, double progress_begin,
                 double progress_end, Task task) {
  std::atomic<std::int64_t> next{0};
  std::atomic<std::int64_t> done{0};
  auto worker = [&](int worker_index) {
    for (std::int64_t item; (item = next.fetch_add(1)) < count;) {
      task(item, worker_index);
      done.fetch_add(1);
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads && t < count; ++t) pool.emplace_back(worker, t);
  auto last_report = std::chrono::steady_clock::now();
  for (std::int64_t item; (item = next.fetch_add(1)) < count;) {
    task(item, 0);
    done.fetch_add(1);
    if (progress && std::chrono::steady_clock::now() - last_report > std::chrono::milliseconds(20)) {
      progress(progress_begin + (progress_end - progress_begin) * double(done.load()) / double(count));
      last_report = std::chrono::steady_clock::now();
    }
  }
  for (auto& thread : pool) thread.join();
  if (progress) progress(progress_end);
}

// The directions from any point of a sphere to any point of a ball around p lie in a cone around the axis
// from the sphere's center to p, of half-angle asin((ball radius + sphere radius) / axis length), provided
// the two are disjoint. Kept as the sine and cosine of the half-angle, so that the cone test needs no
// inverse trigonometry.
struct DirectionCone {
  Eigen::Vector3d axis;  // unit
  double sine = 0, cosine = 1;
};

// The cone for the axis `axis` (from the sphere's center to p), r = ball radius + sphere radius < |axis|.
DirectionCone makeDirectionCone(const Eigen::Vector3d& axis, double r) {
  const double length = axis.norm();
  DirectionCone cone;
  cone.axis = axis / length;
  cone.sine = r / length;
  cone.cosine = std::sqrt((length - r) * (length + r)) / length;
  return cone;
}

// An upper bound on |u - v|^2 for u in cone a and v in the cone of axis `axis` and reach r (disjoint ball and
// sphere: r < |axis|, of squared length length_squared): 2 - 2 cos(theta) for the largest angle theta
// between them, the angle alpha between the axes plus both half-angles (4 once that reaches pi). Sums of
// angles go through their sines and cosines; sin(alpha) comes from a cross product, accurate at small
// angles where acos and 1 - cos^2 are not. Rounding leaves cos(theta) a few ulps of 1 off, which the 1e-12
// added here covers; the caller's relative factor covers the rest.
double coneChordSquaredBound(const DirectionCone& a, const Eigen::Vector3d& axis, double length_squared, double r) {
  const double length = std::sqrt(length_squared);
  const double inverse = 1 / length;
  const double sin_b = r * inverse;
  const double cos_b = std::sqrt((length - r) * (length + r)) * inverse;
  const double cos_alpha = a.axis.dot(axis) * inverse;
  const double sin_alpha = a.axis.cross(axis).norm() * inverse;
  // delta = both half-angles, each below pi / 2.
  const double cos_delta = a.cosine * cos_b - a.sine * sin_b;
  const double sin_delta = a.sine * cos_b + a.cosine * sin_b;
  if (!(cos_alpha > -cos_delta)) return 4.0;  // alpha + delta >= pi: any two unit vectors
  const double cos_theta = cos_alpha * cos_delta - sin_alpha * sin_delta;
  return std::min(4.0, 2 - 2 * cos_theta + 1e-12);
}

std::int64_t physicalMemoryBytes() {
  const long pages = sysconf(_SC_PHYS_PAGES);
  const long page_size = sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page_size <= 0) return std::numeric_limits<std::int64_t>::max();
  return std::int64_t(pages) * page_size;
}

// Topology culling data for one edge of one triangle. Every point p in all three half-spaces
// (p - a) . outward >= 0, (p - a) . (d - a) <= 0 and (p - b) . (d - b) <= 0, where (a, b) is the edge and d
// the opposite corner, has its closest point of the triangle on the edge: projected into the triangle's
// plane it lies beyond the edge's line and outside the Voronoi regions of the other two edges' interiors.
struct EdgeRegion {
  Eigen::Vector3d a, b, outward, to_d_from_a, to_d_from_b;
  // Per half-space, how far its linear function may drop from a voxel's center to its lowest corner (half
  // edge times the 1-norm of the normal) plus the rounding margin: a voxel-sized cube is inside the
  // half-space exactly when its center clears the half-space by this much.
  double outward_reach = 0, from_a_reach = 0, from_b_reach = 0;
  int neighbours_begin = 0, neighbours_end = 0;  // other triangles sharing the edge, in edge_neighbours
  bool usable = false;
};

struct Topology {
  std::vector<std::array<EdgeRegion, 3>> edges;  // per triangle
  std::vector<int> edge_neighbours;
};

Topology makeTopology(const MeshModel& geometry, double half, double margin) {
  const auto& triangles = geometry.mesh.triangles;
  std::unordered_map<std::uint64_t, std::vector<int>> by_edge;
  auto key = [](int u, int v) { return (std::uint64_t(std::min(u, v)) << 32) | std::uint32_t(std::max(u, v)); };
  for (int t = 0; t < int(triangles.size()); ++t) {
    for (int e = 0; e < 3; ++e) by_edge[key(triangles[t][e], triangles[t][(e + 1) % 3])].push_back(t);
  }
  Topology topology;
  topology.edges.resize(triangles.size());
  for (int t = 0; t < int(triangles.size()); ++t) {
    const auto& c = geometry.corners[t];
    const Eigen::Vector3d normal = (c[1] - c[0]).cross(c[2] - c[0]);
    const double scale = std::max({(c[1] - c[0]).squaredNorm(), (c[2] - c[1]).squaredNorm(), (c[0] - c[2]).squaredNorm()});
    const bool degenerate = !(normal.norm() > 1e-8 * scale);
    for (int e = 0; e < 3; ++e) {
      EdgeRegion& region = topology.edges[t][e];
      const int u = triangles[t][e], v = triangles[t][(e + 1) % 3];
      if (degenerate || u == v) continue;
      region.a = c[e];
      region.b = c[(e + 1) % 3];
      const Eigen::Vector3d d = c[(e + 2) % 3];
      Eigen::Vector3d outward = (region.b - region.a).cross(normal);
      if (outward.dot(d - region.a) > 0) outward = -outward;
      region.outward = outward;
      region.to_d_from_a = d - region.a;
      region.to_d_from_b = d - region.b;
      region.outward_reach = half * outward.cwiseAbs().sum() + margin * outward.norm();
      region.from_a_reach = half * region.to_d_from_a.cwiseAbs().sum() + margin * region.to_d_from_a.norm();
      region.from_b_reach = half * region.to_d_from_b.cwiseAbs().sum() + margin * region.to_d_from_b.norm();
      region.neighbours_begin = int(topology.edge_neighbours.size());
      for (int other : by_edge[key(u, v)]) {
        if (other != t) topology.edge_neighbours.push_back(other);
      }
      region.neighbours_end = int(topology.edge_neighbours.size());
      region.usable = region.neighbours_end > region.neighbours_begin;
    }
  }
  return topology;
}

// Whether all of the voxel of center `center` lies strictly inside the edge's region, with a margin so that
// rounding never decides. Each half-space is linear, so its lowest value over the cube is at a corner: the
// center's value minus the reach.
bool voxelInEdgeRegion(const EdgeRegion& region, const Eigen::Vector3d& center) {
  return (center - region.a).dot(region.outward) > region.outward_reach &&
         (center - region.a).dot(region.to_d_from_a) < -region.from_a_reach &&
         (center - region.b).dot(region.to_d_from_b) < -region.from_b_reach;
}

// dmin in units of `unit`, rounded down and saturated, so that unit * result <= dmin (a lower bound).
std::uint8_t quantizeEntryBound(double d_min, double unit) {
  const double units = std::floor(d_min * (1 - 1e-9) / unit);
  return static_cast<std::uint8_t>(std::clamp(units, 0.0, 255.0));
}

// Per-worker scratch of the list pass, reused from voxel to voxel.
struct ListScratch {
  // Topology culling: marks[t] in [last_mark - 3, last_mark] when triangle t is a candidate of the current
  // voxel, saying whether a test excluded it, it stays, may leave or has left; any other value means not a
  // candidate. Sized on first use, so that idle workers cost nothing; 4 bytes per triangle per worker.
  std::vector<std::uint32_t> marks;
  std::uint32_t last_mark = 0;
  std::vector<std::uint8_t> edge_masks;  // per candidate: the edges whose region holds the voxel
  std::vector<std::uint64_t> sort_keys;  // (bound, id)
  std::vector<std::int32_t> candidates;  // of the current voxel, from the Bvh walk
  std::vector<double> quick_bounds;      // per list entry: cubeTriangleQuickBound, before the full bound
};

struct RowLists {
  std::vector<std::int32_t> ids;      // the row's lists, one after another
  std::vector<std::uint8_t> bounds;   // per entry of ids: its quantized dmin (CflModel::list_entry_bounds)
  std::vector<std::uint32_t> counts;  // length of each voxel's list
  std::vector<double> lower_bounds;   // per voxel
};

}  // namespace

int automaticResolution(const TriangleMesh& mesh, double padding) {
  validateMesh(mesh);
  double edge_sum = 0;
  for (const auto& t : mesh.triangles) {
    for (int e = 0; e < 3; ++e) edge_sum += (mesh.vertices[t[e]] - mesh.vertices[t[(e + 1) % 3]]).norm();
  }
  const double mean_edge = edge_sum / (3.0 * mesh.triangles.size());
  const double longest = boundingBox(mesh).size().maxCoeff() * std::max(1.0, padding);
  if (!(mean_edge > 0)) return 8;
  // Voxels of 1.25 mean edges: short-range queries scan the lists of the voxels a triangle of B touches, and
  // finer voxels hold fewer triangles within the prune threshold. Against 2 mean edges (the rule until
  // this commit), instructions per query on 200 poses fell 15% to 20% on the bunny (resolution 39 -> 62)
  // from 0.5% to 50% of the diagonal, about 10% on wuson and 15% on the torus knot (-> 96, the cap);
  // beyond the grid nothing changes (callgrind, same poses). The cost, one run each: the bunny built in
  // 2.07 s instead of 0.78 s and takes 16.3 MB instead of 9.0 MB; wuson 1.17 s and 14.0 MB, the knot 4.14 s
  // and 30.4 MB. Finer voxels pay less and less (bunny 52 -> 64: 5% fewer instructions).
  constexpr double kVoxelMeanEdges = 1.25;
  const double resolution = longest / (kVoxelMeanEdges * mean_edge);
  const double finest = std::clamp(std::round(32 * padding), 64.0, 96.0);
  return static_cast<int>(std::clamp(std::round(resolution), 8.0, finest));
}

CflModel buildCflModel(TriangleMesh mesh, const BuildOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (options.resolution < 0) {
    throw Error("resolution must be >= 1 (or 0 for automatic), got " + std::to_string(options.resolution));
  }
  if (!std::isfinite(options.padding) || options.padding < 1.0) {
    std::ostringstream message;
    message << "padding must be a finite factor >= 1, got " << options.padding;
    throw Error(message.str());
  }
  CflModel model;
  model.geometry = makeMeshModel(std::move(mesh));
  const MeshModel& geometry = model.geometry;
  const int resolution =
      options.resolution > 0 ? options.resolution : automaticResolution(geometry.mesh, options.padding);
  model.grid = makeVoxelGrid(geometry.bounds, resolution, options.padding);
  model.padding = options.padding;
  model.topology_culling = options.topology_culling;
  const VoxelGrid& grid = model.grid;

  const std::int64_t voxel_count = grid.voxelCount();
  const std::int64_t corner_count = grid.cornerCount();
  // The lists average a few entries; the per-voxel and per-corner arrays are the floor.
  const std::int64_t floor_bytes = voxel_count * std::int64_t(sizeof(std::uint32_t) + sizeof(double)) +
                                   corner_count * std::int64_t(sizeof(double) + sizeof(int));
  if (voxel_count > std::numeric_limits<std::uint32_t>::max() / 2 || floor_bytes > physicalMemoryBytes() / 2) {
    std::ostringstream message;
    message << "resolution " << resolution << " needs " << grid.dims[0] << " x " << grid.dims[1] << " x " << grid.dims[2]
            << " = " << voxel_count << " voxels and at least " << floor_bytes << " bytes, more than half of this machine's "
            << physicalMemoryBytes() << " bytes of memory; use a smaller resolution";
    throw Error(message.str());
  }

  const int threads = workerCount(options.threads);
  const double half = 0.5 * grid.voxel_size;
  const Topology topology =
      options.topology_culling ? makeTopology(geometry, half, 1e-9 * grid.voxel_size) : Topology();
  const auto& progress = options.progress;

  // 1. Distance field at the grid corners, with the nearest triangle of each. Rows are walked in order so
  //    that each corner starts from its neighbour's nearest triangle, which usually is its own.
  model.corner_distance.resize(corner_count);
  std::vector<int> corner_triangle(corner_count, 0);
  const int corner_rows = (grid.dims[1] + 1) * (grid.dims[2] + 1);
  parallelFor(corner_rows, threads, progress, 0.0, 0.2, [&](std::int64_t row, int) {
    const int j = static_cast<int>(row % (grid.dims[1] + 1));
    const int k = static_cast<int>(row / (grid.dims[1] + 1));
    int hint = -1;
    for (int i = 0; i <= grid.dims[0]; ++i) {
      const Eigen::Vector3d p = grid.cornerPosition(i, j, k);
      double best = kInfinity;
      int best_triangle = -1;
      if (hint >= 0) {
        const auto& c = geometry.corners[hint];
        best = pointTriangleSquaredDistance(p, c[0], c[1], c[2]);
        best_triangle = hint;
      }
      detail::nearestTriangle(geometry, p, best, best_triangle);
      const std::int64_t index = grid.cornerIndex(i, j, k);
      // Rounded down so that it stays a lower bound however it was rounded on the way.
      model.corner_distance[index] = std::nextafter(std::sqrt(best), 0.0);
      corner_triangle[index] = best_triangle;
      hint = best_triangle;
    }
  });

  // 2. The lists. For voxel V with center c, U = min_k dmax(V, k) over the nearest triangles of the corners
  //    and of c is an upper bound on the distance from any point of V to the mesh. Triangle i belongs to the
  //    list unless dmin(V, i) > U (a Bvh node whose box is farther than U from V holds none that belong),
  //    unless the cone test shows c's nearest triangle strictly closer everywhere in V, and unless
  //    topology culling removes it.
  const int rows = grid.dims[1] * grid.dims[2];
  std::vector<RowLists> row_lists(rows);
  const double half_diagonal = std::sqrt(3.0) * half;
  const double bound_unit = model.entryBoundUnit();
  std::vector<ListScratch> list_scratch(threads);
  parallelFor(rows, threads, progress, 0.2, 0.95, [&](std::int64_t row, int worker) {
    const int j = static_cast<int>(row % grid.dims[1]);
    const int k = static_cast<int>(row / grid.dims[1]);
    RowLists& out = row_lists[row];
    ListScratch& scratch = list_scratch[worker];
    out.counts.reserve(grid.dims[0]);
    out.lower_bounds.reserve(grid.dims[0]);
    for (int i = 0; i < grid.dims[0]; ++i) {
      const Eigen::Vector3d center = grid.voxelCenter(i, j, k);
      Eigen::Vector3d corners[8];
      int upper_candidates[9];
      int upper_candidate_count = 0;
      for (int n = 0; n < 8; ++n) {
        const int ci = i + (n & 1), cj = j + ((n >> 1) & 1), ck = k + ((n >> 2) & 1);
        corners[n] = grid.cornerPosition(ci, cj, ck);
        const int t = corner_triangle[grid.cornerIndex(ci, cj, ck)];
        if (std::find(upper_candidates, upper_candidates + upper_candidate_count, t) ==
            upper_candidates + upper_candidate_count) {
          upper_candidates[upper_candidate_count++] = t;
        }
      }
      // The triangle nearest to the center: a candidate for U, and the reference of the cone test below.
      // The corners' triangles bound the search, but only as a distance just above theirs: the search then
      // prunes the same nodes it would have pruned anyway and still returns the first nearest triangle in
      // its visiting order, so ties (a shared vertex is often nearest) break as in a search from infinity.
      // A tied hint as the reference instead lengthened the bunny's lists slightly.
      double center_squared = kInfinity;
      for (int n = 0; n < upper_candidate_count; ++n) {
        const auto& c = geometry.corners[upper_candidates[n]];
        center_squared = std::min(center_squared, pointTriangleSquaredDistance(center, c[0], c[1], c[2]));
      }
      center_squared = std::nextafter(center_squared * (1 + 1e-12), kInfinity);
      int center_triangle = -1;
      detail::nearestTriangle(geometry, center, center_squared, center_triangle);
      if (center_triangle < 0) {
        // Nothing was found below the corners' bound: their distances were not finite (coordinates near
        // the limits of double). Any triangle serves as U's candidate and the cone's reference, as long as
        // center_squared is its own distance.
        center_squared = kInfinity;
        detail::nearestTriangle(geometry, center, center_squared, center_triangle);
        if (center_triangle < 0) {
          center_triangle = upper_candidates[0];
          const auto& c = geometry.corners[center_triangle];
          center_squared = pointTriangleSquaredDistance(center, c[0], c[1], c[2]);
        }
      }
      if (std::find(upper_candidates, upper_candidates + upper_candidate_count, center_triangle) ==
          upper_candidates + upper_candidate_count) {
        upper_candidates[upper_candidate_count++] = center_triangle;
      }
      double upper = kInfinity;  // squared
      for (int n = 0; n < upper_candidate_count; ++n) {
        const auto& c = geometry.corners[upper_candidates[n]];
        double farthest = 0;
        for (int m = 0; m < 8 && farthest < upper; ++m) {
          farthest = std::max(farthest, pointTriangleSquaredDistance(corners[m], c[0], c[1], c[2]));
        }
        upper = std::min(upper, farthest);
      }
      // Rounded up: a list may hold one triangle too many, never one too few.
      const double upper_bound = std::nextafter(std::sqrt(upper), kInfinity) * (1 + 1e-12);
      const double upper_bound_squared = upper_bound * upper_bound;
      const double center_distance = std::sqrt(center_squared);
      // Cone test. For p in the voxel (within half_diagonal of the center), f(p) = dist(p, i) - dist(p, k)
      // with k = center_triangle changes at most |u_i - u_k| per unit length, u being the unit direction
      // from a triangle's closest point to p. While the voxel's ball stays clear of a sphere around a
      // triangle, u lies in that sphere's DirectionCone, so |u_i - u_k|^2 is at most coneChordSquaredBound.
      // If f(center) > half_diagonal * its root, k is strictly closer than i everywhere in the voxel. Far from
      // the mesh this drops the wide rim of triangles that the dmin/dmax test alone keeps. Any sphere holding
      // the triangle serves, so a Bvh node's sphere and its box distance exclude the whole subtree at once.
      const Eigen::Vector4d& sphere_k = geometry.spheres[center_triangle];
      const Eigen::Vector3d axis_k = center - sphere_k.head<3>();
      const double axis_k_length = axis_k.norm();
      const bool cone_usable = axis_k_length > half_diagonal + sphere_k[3];
      const DirectionCone cone_k =
          cone_usable ? makeDirectionCone(axis_k, half_diagonal + sphere_k[3]) : DirectionCone();
      // Whether k beats every triangle within the sphere (sphere_center, sphere_radius) everywhere in the voxel,
      // given a lower bound `near` on their distances to the center: whether near - dist(center, k) exceeds
      // half_diagonal times the chord bound, compared squared. Margin: a few ulps of every term, relative to
      // the voxel's reach. The chord is at least 2 sin(gamma / 2) >= sin(gamma) for k's half-angle gamma, a
      // cheap necessary condition first (0.999 keeps it strictly weaker, so it only saves time).
      const double chord_floor_k = 0.999 * half_diagonal * cone_k.sine;
      auto coneExcludes = [&](double near, const Eigen::Vector3d& sphere_center, double sphere_radius) {
        const double spare = near - center_distance - 1e-12 * (center_distance + near + half_diagonal);
        if (!(spare > chord_floor_k)) return false;
        const Eigen::Vector3d axis_i = center - sphere_center;
        const double length_i_squared = axis_i.squaredNorm();
        const double r_i = half_diagonal + sphere_radius;
        if (!(length_i_squared > r_i * r_i)) return false;
        const double chord_squared = coneChordSquaredBound(cone_k, axis_i, length_i_squared, r_i);
        return spare * spare > half_diagonal * half_diagonal * chord_squared * (1 + 3e-9);
      };

      // Triangles that may belong: a Bvh walk that skips nodes whose box is farther than U from the voxel's
      // cube (then dmin > U for all below), or that the cone test excludes as a whole.
      std::vector<std::int32_t>& candidates = scratch.candidates;
      candidates.clear();
      const auto& nodes = geometry.bvh.nodes;
      int stack[128];  // see detail::nearestTriangle for why this is enough
      int top = 0;
      stack[top++] = 0;
      while (top > 0) {
        const BvhNode& node = nodes[stack[--top]];
        const Eigen::Vector3d outside =
            (node.box.min - center).cwiseMax(center - node.box.max).cwiseMax(0.0);
        if ((outside.array() - half).max(0.0).matrix().squaredNorm() > upper_bound_squared) continue;
        if (cone_usable && coneExcludes(outside.norm(), node.center, node.radius)) continue;
        if (node.isLeaf()) {
          candidates.insert(candidates.end(), geometry.bvh.triangle_ids.begin() + node.first,
                            geometry.bvh.triangle_ids.begin() + node.first + node.count);
        } else {
          stack[top++] = node.first;
          stack[top++] = node.first + 1;
        }
      }
      const std::uint32_t candidate_count = static_cast<std::uint32_t>(candidates.size());

      // Paper section 3.6, in a form that is provably conservative on any mesh: triangle i may leave the
      // list when every point of the voxel has its closest point of i on an edge shared with a triangle j
      // (its witness), so that j is at least as close everywhere. It does leave when some witness stays,
      // is missing from the list, or has itself left through such a chain. Why that is safe: a triangle
      // missing from the list is strictly beaten everywhere by another, so for any point p, following
      // witnesses from one of p's nearest triangles never increases the distance and ends at a triangle
      // that stays (a missing one would be strictly beaten, so not nearest). Witnesses that only lean on
      // each other in a cycle all stay. The result is the least fixed point of a monotone rule, so it
      // does not depend on the order of the list.
      //
      // It runs before the exclusion tests, with every candidate counted as listed, and again after them,
      // with the excluded ones counted as missing: the first round is the cheap one and removes most of the
      // triangles that the costly tests would otherwise examine, and since it only drops what the rule
      // drops, the second round reaches the same least fixed point as a single round after the tests.
      const bool culling = options.topology_culling && candidate_count > 1;
      std::uint32_t missing = 0, stays = 0, undecided = 0, left = 0;
      auto propagate = [&](std::uint32_t size) {  // over candidates[0, size)
        for (bool changed = true; changed;) {
          changed = false;
          for (std::uint32_t n = 0; n < size; ++n) {
            if (scratch.marks[candidates[n]] != undecided) continue;
            bool drop = false;
            for (int e = 0; e < 3 && !drop; ++e) {
              if (!(scratch.edge_masks[n] >> e & 1)) continue;
              const EdgeRegion& region = topology.edges[candidates[n]][e];
              for (int m = region.neighbours_begin; m < region.neighbours_end && !drop; ++m) {
                drop = scratch.marks[topology.edge_neighbours[m]] != undecided;
              }
            }
            if (drop) {
              scratch.marks[candidates[n]] = left;
              changed = true;
            }
          }
        }
      };
      bool any_droppable = false;
      if (culling) {
        if (scratch.marks.empty() || scratch.last_mark > std::numeric_limits<std::uint32_t>::max() - 4) {
          scratch.marks.assign(geometry.mesh.triangles.size(), 0);
          scratch.last_mark = 0;
        }
        missing = (scratch.last_mark += 4) - 3;  // excluded by a test; any older mark: never a candidate
        stays = missing + 1;                    // listed, not droppable
        undecided = missing + 2;                // droppable, not yet shown to leave
        left = missing + 3;                     // shown to leave
        scratch.edge_masks.assign(candidate_count, 0);
        for (std::uint32_t n = 0; n < candidate_count; ++n) {
          const auto& regions = topology.edges[candidates[n]];
          for (int e = 0; e < 3; ++e) {
            if (regions[e].usable && voxelInEdgeRegion(regions[e], center)) scratch.edge_masks[n] |= 1 << e;
          }
          scratch.marks[candidates[n]] = scratch.edge_masks[n] ? undecided : stays;
          any_droppable = any_droppable || scratch.edge_masks[n];
        }
        if (any_droppable) propagate(candidate_count);
      }

      // The exclusion tests, on what the first round kept. The full separating-axis bound comes after
      // culling, for the entries that stay: it is the costly test and seldom excludes, so culling sees
      // those few as listed, which may keep more, never fewer (a witness that is listed or missing is good
      // either way).
      std::uint32_t count = 0;
      scratch.quick_bounds.clear();
      bool any_excluded = false;
      for (std::uint32_t n = 0; n < candidate_count; ++n) {
        const int t = candidates[n];
        if (culling && scratch.marks[t] == left) continue;
        const auto& c = geometry.corners[t];
        Eigen::Vector3d closest;
        const double d_center = std::sqrt(pointTriangleSquaredDistance(center, c[0], c[1], c[2], &closest));
        bool excluded = d_center - half_diagonal > upper_bound;
        double d_min = 0;
        if (!excluded) {
          d_min = detail::cubeTriangleQuickBound(center, half, c[0], c[1], c[2], closest);
          excluded = d_min > upper_bound;
        }
        if (!excluded && cone_usable && t != center_triangle) {
          const Eigen::Vector4d& sphere_i = geometry.spheres[t];
          excluded = coneExcludes(d_center, sphere_i.head<3>(), sphere_i[3]);
        }
        if (excluded) {
          if (culling) scratch.marks[t] = missing;
          any_excluded = true;
          continue;
        }
        candidates[count] = t;  // compacted in place: n >= count
        if (culling) scratch.edge_masks[count] = scratch.edge_masks[n];
        scratch.quick_bounds.push_back(d_min);
        ++count;
      }
      if (culling && any_droppable && any_excluded) propagate(count);
      // What culling kept, through the full bound. The lower bound of the voxel: the closest triangle to any
      // of its points is listed, so the smallest listed dmin bounds the voxel-mesh distance from below.
      const std::size_t list_begin = out.ids.size();
      double lower = kInfinity;
      for (std::uint32_t n = 0; n < count; ++n) {
        const int t = candidates[n];
        if (culling && scratch.marks[t] == left) continue;
        const auto& c = geometry.corners[t];
        const double d_min =
            detail::cubeTriangleSeparatingAxisBound(center, half, c[0], c[1], c[2], scratch.quick_bounds[n]);
        if (d_min > upper_bound) continue;
        lower = std::min(lower, d_min);
        out.ids.push_back(t);
        out.bounds.push_back(quantizeEntryBound(d_min, bound_unit));
      }
      count = static_cast<std::uint32_t>(out.ids.size() - list_begin);
      std::int32_t* list = out.ids.data() + list_begin;
      std::uint8_t* bounds = out.bounds.data() + list_begin;
      // The query scans a list in this order and stops at the first entry whose bound reaches its best
      // distance so far.
      scratch.sort_keys.clear();
      for (std::uint32_t n = 0; n < count; ++n) {
        scratch.sort_keys.push_back(std::uint64_t(bounds[n]) << 32 | std::uint32_t(list[n]));
      }
      std::sort(scratch.sort_keys.begin(), scratch.sort_keys.end());
      for (std::uint32_t n = 0; n < count; ++n) {
        bounds[n] = static_cast<std::uint8_t>(scratch.sort_keys[n] >> 32);
        list[n] = static_cast<std::int32_t>(scratch.sort_keys[n] & 0xffffffffu);
      }
      out.counts.push_back(count);
      out.lower_bounds.push_back(std::nextafter(lower, 0.0) * (1 - 1e-12));
    }
  });

  // 3. Flatten in voxel order, storing identical lists once.
  model.voxel_list.resize(voxel_count);
  model.voxel_lower_bound.resize(voxel_count);
  model.list_offsets.assign(1, 0);
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> lists_by_hash;
  std::int64_t total_length = 0, longest = 0;
  for (int row = 0; row < rows; ++row) {
    const RowLists& in = row_lists[row];
    const int j = row % grid.dims[1];
    const int k = row / grid.dims[1];
    std::size_t offset = 0;
    for (int i = 0; i < grid.dims[0]; ++i) {
      const std::int64_t v = grid.voxelIndex(i, j, k);
      const std::int32_t* list = in.ids.data() + offset;
      const std::uint8_t* bounds = in.bounds.data() + offset;
      const std::uint32_t length = in.counts[i];
      offset += length;
      total_length += length;
      longest = std::max<std::int64_t>(longest, length);
      model.voxel_lower_bound[v] = in.lower_bounds[i];
      std::uint64_t hash = 1469598103934665603ull ^ length;
      for (std::uint32_t n = 0; n < length; ++n) {
        hash = (hash ^ (std::uint32_t(list[n]) | std::uint64_t(bounds[n]) << 32)) * 1099511628211ull;
      }
      auto& same_hash = lists_by_hash[hash];
      std::uint32_t found = std::numeric_limits<std::uint32_t>::max();
      for (std::uint32_t id : same_hash) {
        const std::uint32_t begin = model.list_offsets[id], end = model.list_offsets[id + 1];
        if (end - begin == length && std::equal(list, list + length, model.list_triangles.begin() + begin) &&
            std::equal(bounds, bounds + length, model.list_entry_bounds.begin() + begin)) {
          found = id;
          break;
        }
      }
      if (found == std::numeric_limits<std::uint32_t>::max()) {
        found = static_cast<std::uint32_t>(model.list_offsets.size() - 1);
        model.list_triangles.insert(model.list_triangles.end(), list, list + length);
        model.list_entry_bounds.insert(model.list_entry_bounds.end(), bounds, bounds + length);
        model.list_offsets.push_back(static_cast<std::uint32_t>(model.list_triangles.size()));
        same_hash.push_back(found);
      }
      model.voxel_list[v] = found;
    }
    row_lists[row] = RowLists();  // release as we go
  }

  BuildStatistics& stats = model.statistics;
  stats.resolution = resolution;
  stats.voxel_count = voxel_count;
  stats.average_list_length = double(total_length) / double(voxel_count);
  stats.longest_list = longest;
  stats.distinct_lists = std::int64_t(model.list_offsets.size()) - 1;
  stats.memory_bytes = std::int64_t(model.voxel_list.size() * sizeof(std::uint32_t) +
                                    model.list_offsets.size() * sizeof(std::uint32_t) +
                                    model.list_triangles.size() * sizeof(std::int32_t) +
                                    model.list_entry_bounds.size() * sizeof(std::uint8_t) +
                                    model.voxel_lower_bound.size() * sizeof(double) +
                                    model.corner_distance.size() * sizeof(double) +
                                    geometry.mesh.vertices.size() * sizeof(Eigen::Vector3d) +
                                    geometry.mesh.triangles.size() * sizeof(std::array<int, 3>) +
                                    geometry.corners.size() * sizeof(std::array<Eigen::Vector3d, 3>) +
                                    geometry.spheres.size() * sizeof(Eigen::Vector4d) +
                                    geometry.planes.size() * sizeof(Eigen::Vector4d) +
                                    geometry.leaf_corners.size() * sizeof(std::array<Eigen::Vector3d, 3>) +
                                    geometry.leaf_spheres.size() * sizeof(Eigen::Vector4d) +
                                    geometry.leaf_planes.size() * sizeof(Eigen::Vector4d) +
                                    geometry.bvh.nodes.size() * sizeof(BvhNode) +
                                    geometry.bvh.triangle_ids.size() * sizeof(std::int32_t));
  stats.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (progress) progress(1.0);
  return model;
}

}  // namespace cfl
