#pragma once
/// @file
/// Test-only switches and counts of buildCflModel (src/cfl_builder.cpp): the switches may change how long a
/// build takes, never the model it builds, and the tests check exactly that.

#include <cstdint>

namespace cfl {
struct MeshModel;
}

namespace cfl::detail {

/// Whether a cell may decide to split before its list is complete, once the split rule is certain to hold
/// whatever the rest of the list (true unless a test turns it off). Read once at the start of each build:
/// set it only while no build runs.
void setEarlySplitDecisions(bool enabled);

/// How many cells have split that way since the program started, over all builds (thread safe).
std::int64_t earlySplitDecisionCount();

/// How many (triangle, edge neighbour) entries topology culling keeps for `geometry`: what bounds its memory
/// and the work of each culling test.
std::int64_t topologyNeighbourCount(const MeshModel& geometry);

}  // namespace cfl::detail
