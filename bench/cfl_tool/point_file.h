#pragma once
/// @file
/// The point file of `cfl sdf`: one point per line, three numbers separated by spaces or commas.

#include <Eigen/Core>

#include <iosfwd>
#include <string>
#include <vector>

namespace cfl::tool {

/// Reads points, one "x y z" (or "x,y,z") per line; '#' starts a comment, blank lines are skipped. Throws
/// cfl::Error "SOURCE:LINE: reason" for a line without exactly three finite numbers.
std::vector<Eigen::Vector3d> readPoints(std::istream& in, const std::string& source);

}  // namespace cfl::tool
