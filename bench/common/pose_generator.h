#pragma once
/// @file
/// The poses every benchmark uses, shared by `cfl bench`, `cfl paper` and the Google Benchmark suites so
/// that their figures describe the same queries.

#include "cfl/mesh.h"

#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <random>
#include <vector>

namespace cfl::bench {

/// The distance between mesh A at the identity and mesh B at pose X_WB. The benchmarks pass FCL's OBBRSS
/// distance (the baseline), so poses do not depend on the code being measured.
using DistanceFunction = std::function<double(const Eigen::Isometry3d& X_WB)>;

/// Separation bands as fractions of A's bounding-box diagonal, the default of `cfl bench`:
/// 0 (overlapping), 0.5%, 2%, 10%, 50%.
/// A pose of a shape at distance `target` from a mesh whose bounding box has center `center` and diagonal
/// `diagonal`, for the shape benchmarks: a uniformly random rotation and a random ray from the center
/// outwards (both drawn from `rng`, in that order), the outermost crossing of `target` along the ray found by
/// marching in from one diagonal out in steps of 2% of it, then 60 bisection steps. `distance(X)` is the
/// shape's distance to the mesh at pose X (mesh frame = world).
Eigen::Isometry3d placeShapeOnRay(const Eigen::Vector3d& center, double diagonal, double target,
                                  std::mt19937_64& rng, const DistanceFunction& distance);

std::vector<double> defaultBands();

/// Poses of B for one band.
struct BandPoses {
  double band = 0;             ///< Fraction of A's bounding-box diagonal.
  double target_distance = 0;  ///< band * diagonal.
  std::vector<Eigen::Isometry3d> poses;  ///< X_WB, A being at the identity.
  std::vector<double> distances;         ///< The distance function's value at each pose.
};

/// Relative tolerance on the achieved distance of a separated pose: |d - target| <= kBandTolerance * target.
constexpr double kBandTolerance = 0.01;

/// `count` poses of B, each a uniformly random rotation R and a uniformly random unit direction u; B's
/// bounding-box center is placed at A's plus s * u, with the offset s found by bisection so that:
/// - band > 0: distance(X_WB) is within kBandTolerance of band * diagonal(A). The distance is 1-Lipschitz
///   in s, which lets every evaluation shrink the bracket from both sides.
/// - band == 0: the meshes overlap (distance 0): half the offset at which they stop touching, else a
///   quarter, else zero.
/// A draw whose band cannot be reached (already too far apart at s = 0, or not overlapping) is replaced by a
/// new draw. Deterministic for a given seed, band and pair of meshes: the random stream is seeded from
/// `seed` and the band's value, so a band gets the same poses whatever other bands are asked for.
/// Throws cfl::Error for band < 0, a non-finite band, empty bounds, or when 100 draws in a row fail.
BandPoses generateBandPoses(const Aabb& bounds_a, const Aabb& bounds_b, double band, int count,
                            std::uint64_t seed, const DistanceFunction& distance);

/// A smooth motion of B close to A, the paper's use case (a dynamics simulator queries the same pair every
/// step).
struct MovingPoses {
  double separation = 0;                 ///< Fraction of A's bounding-box diagonal.
  double target_distance = 0;            ///< separation * diagonal.
  std::vector<Eigen::Isometry3d> poses;  ///< X_WB per frame, A being at the identity.
  std::vector<double> distances;         ///< The distance function's value at each frame.
  double median_step = 0;                ///< Median translation of B's box center between frames.
  double max_step = 0;                   ///< Largest such translation (a jump where the outermost feature changes).
  double rotation_step = 0;              ///< Rotation of B between frames, radians (constant).
};

/// `frames` poses of B orbiting A while rolling. Frame k has t = k / frames in [0, 1): B's direction from A's
/// box center sweeps one full turn around a random axis (with a small wobble across it), and B turns twice
/// about another random axis, both smooth in t. Along the direction B comes in from far away until the
/// distance drops to within 0.1% of separation * diagonal(A): sphere tracing (steps of distance - target,
/// which cannot overshoot a 1-Lipschitz function), so B rests on the outermost part of A it meets, as an
/// object sliding over A would. Deterministic for a given seed. Throws cfl::Error for separation <= 0, or a
/// frame where the target cannot be reached (the meshes overlap at the centers' coincidence and no offset
/// reaches the target, which a separation > 0 rules out for bounded meshes).
MovingPoses generateMovingPoses(const Aabb& bounds_a, const Aabb& bounds_b, double separation, int frames,
                                std::uint64_t seed, const DistanceFunction& distance);

/// The median and 90th percentile (nearest rank) of `values`; 0 for an empty vector.
double median(std::vector<double> values);
double percentile(std::vector<double> values, double fraction);

}  // namespace cfl::bench
