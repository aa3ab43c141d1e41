#pragma once
/// @file
/// The optional sections of `cfl bench`: moving objects with warm starts (--moving) and approximate queries
/// (--rel-err / --abs-err). Each prints its own table and checks every CFL answer against FCL OBBRSS, or
/// brute force where the two disagree (Referee).

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

}  // namespace cfl::tool
