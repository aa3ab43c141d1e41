#include "referee.h"

#include "cfl/cfl_query.h"

#include <algorithm>
#include <cmath>

namespace cfl::tool {

double Referee::reference(const Eigen::Isometry3d& X_WB, double obbrss, std::initializer_list<double> cfl_answers) {
  // Written so that a NaN anywhere counts as a disagreement.
  const bool agree = std::all_of(cfl_answers.begin(), cfl_answers.end(),
                                 [&](double d) { return std::abs(d - obbrss) <= tolerance_; });
  if (agree) return obbrss;
  ++brute_force_checks_;
  const double truth = bruteForceDistance(a_, Eigen::Isometry3d::Identity(), b_, X_WB).distance;
  const double fcl_error = std::abs(obbrss - truth);
  if (!(fcl_error <= tolerance_)) {
    ++fcl_errors_;
    largest_fcl_error_ = std::max(largest_fcl_error_, fcl_error);
  }
  return truth;
}

}  // namespace cfl::tool
