#pragma once
/// @file
/// The optional sections of `cfl bench`: moving objects with warm starts (--moving), approximate queries
/// (--rel-err / --abs-err), and the other query kinds: points, shapes and penetration. Each prints its own
/// table next to FCL's answer on the same queries and checks CFL's.

#include "cfl/cfl_query.h"
#include "fcl_baseline.h"
#include "measure.h"
#include "pose_generator.h"
#include "referee.h"

#include <cstdint>
#include <iosfwd>
#include <vector>

namespace cfl::tool {

/// What every section measures on: A (with CFLs) at the identity, B as a mesh, their OBBRSS twins.
struct SectionContext {
  const CflModel& cfl_a;
  const MeshModel& model_b;
  const bench::FclModel& obbrss_a;
  const bench::FclModel& obbrss_b;
  double diagonal;  ///< A's bounding-box diagonal, the scale of every tolerance.
  int repeats;
  Clock clock;
  Order order;
};

/// `frames` frames of bench::generateMovingPoses at `separation` (fraction of the diagonal); times CFL cold,
/// CFL warm (hint = the previous frame's answer) and OBBRSS per frame. Returns false when a CFL answer
/// differs from the reference (Referee) by more than 1e-9 of the diagonal (the row is marked MISMATCH).
bool runMovingSection(const SectionContext& context, int frames, double separation, std::uint64_t seed,
                      std::ostream& out);

/// On each band's poses: exact CFL, CFL with `options` (rel_err, abs_err) and OBBRSS. Returns false when
/// exact CFL differs from the reference (Referee) by more than 1e-9 of the diagonal, or an approximate
/// answer d leaves [true, min(true * (1 + rel_err), true + abs_err)] by more than that (true = the reference).
bool runApproximateSection(const SectionContext& context, const std::vector<bench::BandPoses>& bands,
                           const DistanceOptions& options, std::ostream& out);

/// --points N (query_kind_sections.cpp): N points near A's surface (within 5% of the diagonal) and N uniform
/// in twice A's box; per point, CFL's point query (unsigned, and signed when A is closed) against FCL's
/// distance of a radius-0 sphere to A's OBBRSS, plus the whole set through computePointDistances on all
/// threads. Returns false when a CFL distance differs from the reference (FCL, or brute force over all
/// triangles where the two disagree) by more than 1e-9 of the diagonal.
bool runPointSection(const SectionContext& context, int count, std::uint64_t seed, std::ostream& out);

/// --shapes N: a sphere, a capsule and a box at each positive band (fraction of the diagonal), N poses each,
/// placed by bisection on CFL's exact distance; the core's queries against FCL's shape-vs-OBBRSS distance.
/// Returns false when the two differ by more than 1e-9 of the diagonal for spheres, 1e-5 for capsules and
/// boxes (FCL's GJK tolerance).
bool runShapeSection(const SectionContext& context, const std::vector<double>& bands, int poses,
                     std::uint64_t seed, std::ostream& out);

/// --penetration N: A against itself at N overlapping poses; computePenetration against fcl::collide with
/// contacts (first contact, every contact). A mesh that is not closed is skipped with its reason. Returns
/// false when an interval is wider than its tolerance, a depth is not positive, or a witness pair is not
/// depth apart.
bool runPenetrationSection(const SectionContext& context, int poses, std::uint64_t seed, std::ostream& out);

}  // namespace cfl::tool
