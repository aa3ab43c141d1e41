#pragma once
/// @file
/// Many distance queries at once, spread over threads: the shape of work in sampling-based planning, where
/// one robot link (B) is checked at thousands of configurations against a fixed obstacle (A).

#include "cfl/cfl_query.h"

#include <Eigen/Geometry>

#include <cstddef>
#include <vector>

namespace cfl {

/// Options of a batch query.
struct BatchOptions {
  /// Options of every single query (mode, tolerances, hint); the same for all poses.
  DistanceOptions distance;
  /// Worker threads, the calling thread included; 0 means every hardware thread the process may run on.
  /// Never more than the number of poses, nor than TBB runs at once (the hardware threads, unless the program
  /// raised it with a tbb::global_control). The batch runs in a oneTBB task arena of this many slots, served
  /// by TBB's shared worker pool, started once per process. The results do not depend on it.
  int threads = 0;
  /// Poses handed to a thread at a time. Small chunks balance the load (query cost varies a lot with the
  /// distance); 0 picks one from the batch size and thread count.
  int chunk_size = 0;
};

/// results[i] = computeDistance(a, X_WA, b, X_WB[i], options.distance) for i in [0, count), bit-identical to
/// the serial calls, whatever the thread count and scheduling (each query is independent and deterministic).
///
/// Every pose is validated before any work starts; a bad one throws cfl::Error naming its index, e.g.
/// "X_WB[17]: ...", and leaves `results` untouched. `results` must hold `count` elements and may not alias
/// the poses. The models are only read, so other threads may query them meanwhile. Memory: TBB's worker
/// threads, kept for later batches; no allocation per query beyond computeDistance's own.
void computeDistances(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                      const Eigen::Isometry3d* X_WB, std::size_t count, DistanceResult* results,
                      const BatchOptions& options = {});

/// As above with CFLs on both sides (the CflModel overload of computeDistance).
void computeDistances(const CflModel& a, const Eigen::Isometry3d& X_WA, const CflModel& b,
                      const Eigen::Isometry3d* X_WB, std::size_t count, DistanceResult* results,
                      const BatchOptions& options = {});

/// Convenience form returning one result per pose of B.
std::vector<DistanceResult> computeDistances(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                                             const std::vector<Eigen::Isometry3d>& X_WB,
                                             const BatchOptions& options = {});

/// The thread count a batch of `count` poses would use with `requested` threads (0 = all hardware threads),
/// after the caps of BatchOptions::threads.
int batchThreadCount(int requested, std::size_t count);

}  // namespace cfl
