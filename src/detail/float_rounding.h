#pragma once
/// @file
/// Internal: doubles rounded to float in a chosen direction, for bounds stored in float that must stay bounds.

#include <cmath>
#include <limits>

namespace cfl::detail {

/// The largest float at most x, and the smallest at least x: an infinity where x is beyond float's range
/// (validateMesh allows coordinates up to 1e50), which the tests on such bounds take as no bound on that side.
inline float floatBelow(double x) {
  float f = static_cast<float>(x);
  if (double(f) > x) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}
inline float floatAbove(double x) {
  float f = static_cast<float>(x);
  if (double(f) < x) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

}  // namespace cfl::detail
