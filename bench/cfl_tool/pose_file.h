#pragma once
/// @file
/// Pose files and the distance CSV of `cfl distance`.
///
/// Pose file: one pose of mesh B per line, 12 numbers, the row-major 3x4 matrix [R | t] of X_WB
/// (r00 r01 r02 t0 r10 r11 r12 t1 r20 r21 r22 t2), separated by spaces, tabs and/or commas. Everything after
/// a '#' is a comment; blank lines are skipped. R must be a rotation (orthonormal, determinant +1, to 1e-6).

#include <Eigen/Geometry>

#include <iosfwd>
#include <string>
#include <vector>

namespace cfl::tool {

/// Reads every pose of `in`. Throws cfl::Error "SOURCE:LINE: reason" for the first malformed line (wrong
/// count of numbers, a word that is not a finite number, a matrix that is not a rotation); `source` names
/// the stream ("poses.txt", "<stdin>"). An input without any pose is not an error (zero rows). O(size).
std::vector<Eigen::Isometry3d> readPoses(std::istream& in, const std::string& source);

/// One pose line as readPoses expects it, with 17 significant digits (reads back bit-identically).
std::string formatPose(const Eigen::Isometry3d& X);

/// The header of `cfl distance` output; with --method both, ",method" is appended.
constexpr const char* kDistanceCsvHeader = "pose,distance,ax,ay,az,bx,by,bz,tri_a,tri_b,micros";

/// One row of `cfl distance`: the answer for pose `pose` (0-based index in the pose file), closest points in
/// the world frame (A at the identity), the time of the query in microseconds, and for --method both the
/// method ("cfl" or "obbrss"; empty otherwise).
struct DistanceRow {
  long pose = 0;
  double distance = 0;
  Eigen::Vector3d point_a = Eigen::Vector3d::Zero();
  Eigen::Vector3d point_b = Eigen::Vector3d::Zero();
  int triangle_a = -1;
  int triangle_b = -1;
  double micros = 0;
  std::string method;
};

/// The CSV line of `row` (no newline); doubles with 17 significant digits, micros with 3 decimals.
std::string formatDistanceRow(const DistanceRow& row);

/// Parses `cfl distance` output: the header line (with or without the method column), then rows of that
/// shape. Throws cfl::Error "SOURCE:LINE: reason" for a wrong header, a wrong field count or a field that is
/// not a number of the right kind.
std::vector<DistanceRow> readDistanceCsv(std::istream& in, const std::string& source);

}  // namespace cfl::tool
