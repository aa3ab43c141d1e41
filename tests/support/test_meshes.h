#pragma once
/// @file
/// Test support: mesh generators, poses and an independent point-mesh distance reference.
///
/// Nothing here calls the library's distance kernels, so tests can check the library against it. The one
/// exception is placeAtDistance, which takes the distance function to bisect on from its caller: it only
/// shapes the distribution of test inputs, and every assertion is made against a reference.
/// Generated meshes are small (a few hundred to ~1500 triangles) so that brute force stays cheap.

#include "cfl/mesh.h"

#include <Eigen/Geometry>

#include <functional>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace cfl::test {

using Rng = std::mt19937_64;

/// A mesh with the name that test failures print.
struct NamedMesh {
  std::string name;
  TriangleMesh mesh;
};

/// A closed torus around the z axis: `major_segments` x `minor_segments` quads, two triangles each.
TriangleMesh makeTorus(double major_radius = 1.0, double minor_radius = 0.35, int major_segments = 24,
                       int minor_segments = 12);

/// A closed tube of radius `tube_radius` around the (p, q) torus knot
/// ((2 + cos(q t)) cos(p t), (2 + cos(q t)) sin(p t), -sin(q t)) scaled by `scale`. Non-convex everywhere,
/// with many pairs of distant-in-topology but close-in-space triangles.
TriangleMesh makeTorusKnot(int p = 2, int q = 3, double scale = 1.0, double tube_radius = 0.3, int segments = 64,
                           int tube_segments = 6);

/// `triangle_count` independent random triangles (three private vertices each) with centers uniform in
/// [-extent, extent]^3 and corners within `triangle_size` of their center. Deterministic in `seed`.
TriangleMesh makeTriangleSoup(int triangle_count, std::uint64_t seed, double extent = 1.0,
                              double triangle_size = 0.25);

/// An open hemisphere (z >= 0) of radius `radius`, without its equatorial cap.
TriangleMesh makeHemisphere(double radius = 1.0, int rings = 8, int segments = 24);

/// An open height field z = amplitude * sin(x) cos(y) over [-size, size]^2 with n x n quads.
TriangleMesh makeWavySheet(double size = 1.5, double amplitude = 0.4, int n = 16);

/// A torus with added junk that validateMesh must accept and the library must handle: zero-area triangles
/// (three equal indices, two equal indices, exactly collinear corners), duplicated triangles (same indices,
/// permuted indices, and copies with their own duplicated vertices), a fan of 4 triangles on one edge
/// (non-manifold edge), flipped orientations, and an unused vertex far away. The torus has
/// `major_segments` x `minor_segments` quads (at least 8 x 6, which the junk refers to).
TriangleMesh makeMessyMesh(int major_segments = 16, int minor_segments = 8);

/// Two closed shapes that pass through each other, as one soup: a torus and a box whose bar crosses the
/// torus' tube, plus a second torus whose tube cuts through the first's. Each torus has
/// `major_segments` x `minor_segments` quads.
TriangleMesh makeSelfIntersectingMesh(int major_segments = 16, int minor_segments = 8);

/// A closed thin plate [-size, size]^2 x [-thickness / 2, thickness / 2]: each face an n x n grid of quads,
/// two triangles each, welded to the other by a strip of quads around the rim (4 n (n + 2) triangles).
TriangleMesh makeThinPlate(double size = 1.0, double thickness = 0.05, int n = 12);

/// A closed slab [0, 10]^2 x [0, 1] whose top carries an n x n grid of tiny quads on [4.9, 5.1]^2, joined to
/// the top's corners by fans of long slivers: tiny triangles next to huge thin ones, as adaptive remeshers
/// leave them (2 n^2 + 4 n + 14 triangles).
TriangleMesh makeLocallyRefinedSlab(int n = 10);

/// A closed axis-aligned box, 12 triangles.
TriangleMesh makeBox(const Eigen::Vector3d& min, const Eigen::Vector3d& max);

/// Concatenates two soups (no vertex merging).
TriangleMesh merge(const TriangleMesh& a, const TriangleMesh& b);

/// Meshes whose features line up with a query shape's or degenerate, for the tests of feature pruning
/// (which faces, edges and corners of a triangle and a shape can be closest), by name: "blocks", two
/// axis-aligned boxes whose faces lie on a quarter-unit grid; "messy", makeMessyMesh; "hemisphere", an open
/// makeHemisphere.
std::vector<std::pair<std::string, TriangleMesh>> makeFeaturePruningMeshes();

/// Reads the `v` and `f` lines of a Wavefront OBJ file (polygons fan-triangulated, `a/b/c` and negative
/// indices understood). Independent of the library's loaders. Throws std::runtime_error on failure.
TriangleMesh readObj(const std::string& path);

/// The bundled Stanford bunny, data/bunny.obj (3674 triangles).
TriangleMesh loadBunny();

/// A uniformly distributed rotation (normalized 4D Gaussian quaternion).
Eigen::Matrix3d randomRotation(Rng& rng);

/// A random rigid pose: uniform rotation, translation uniform in [-translation_range, translation_range]^3.
Eigen::Isometry3d randomPose(Rng& rng, double translation_range);

/// Given a distance function of B's pose (A fixed), returns a pose of B with a random rotation whose
/// distance is `target` to within `tolerance`, found by bisection on the translation along a random
/// direction from the pose that puts B's box center on `center_a` (world). `distance` should be exact
/// (or at least continuous); `target` 0 returns an overlapping pose. `bounds_b` is in B's frame.
Eigen::Isometry3d placeAtDistance(const std::function<double(const Eigen::Isometry3d& X_WB)>& distance,
                                  const Eigen::Vector3d& center_a, const Aabb& bounds_b, double target,
                                  double tolerance, Rng& rng);

/// Independent reference: squared distance from p to triangle (a, b, c), by projection onto the plane
/// (when the projection is inside) or else the closest of the three edges. Triangles whose area is
/// negligible are treated as their three edges. Written for obviousness, not speed.
double referencePointTriangleSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                             const Eigen::Vector3d& b, const Eigen::Vector3d& c);

/// Independent reference: distance from p to the mesh transformed by X (p in the same frame as X's
/// output). `triangle` receives the id of a closest triangle when not null.
double referencePointMeshDistance(const TriangleMesh& mesh, const Eigen::Vector3d& p,
                                  const Eigen::Isometry3d& X = Eigen::Isometry3d::Identity(),
                                  int* triangle = nullptr);

/// A point of triangle t of `mesh` uniformly distributed over it (mesh frame).
Eigen::Vector3d randomPointOnTriangle(const TriangleMesh& mesh, int t, Rng& rng);

}  // namespace cfl::test
