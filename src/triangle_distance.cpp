// The public distance kernels: detail/triangle_distance_kernels.inc compiled for the baseline instruction set.

#include "cfl/triangle_distance.h"

#include "detail/exact_arithmetic.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>

namespace cfl {

#include "detail/triangle_distance_kernels.inc"

}  // namespace cfl
