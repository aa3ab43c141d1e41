#pragma once
/// @file
/// The one exception type of the library.

#include <stdexcept>
#include <string>

namespace cfl {

/// Thrown for every invalid input the library detects: an empty or malformed mesh, a non-finite
/// coordinate, an out-of-range index, a bad option, a bad pose, a corrupt file. The message names the
/// culprit (which triangle, which vertex, which value, which file) so that it can be shown to a user as is.
/// Programming errors inside the library are not reported this way; they are bugs.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace cfl
