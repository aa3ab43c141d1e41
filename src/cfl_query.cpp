#include "cfl/cfl_query.h"

#include "cfl/error.h"
#include "cfl/query_kernels.h"
#include "cfl/triangle_distance.h"
#include "detail/box_triangle_bound.h"
#include "detail/exact_arithmetic.h"
#include "detail/nearest_triangle.h"

#include <Eigen/Geometry>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <sstream>
#include <string>
#include <tuple>

// The bounds' grid lookups (roundToInteger) and the distance kernels' error-free transformations rely on
// IEEE double arithmetic as written; -ffast-math would reassociate them into wrong answers.
#if defined(__FAST_MATH__)
#error "cfl must be compiled without -ffast-math: its exact queries rely on IEEE double rounding"
#endif

// Inlining decisions measured in instructions per query (see each use); other compilers take their own.
#if defined(__GNUC__)
#define CFL_NOINLINE __attribute__((noinline))
#define CFL_ALWAYS_INLINE __attribute__((always_inline))
#else
#define CFL_NOINLINE
#define CFL_ALWAYS_INLINE
#endif


namespace cfl {

void validatePose(const Eigen::Isometry3d& X, const char* what) {
  const Eigen::Matrix4d& m = X.matrix();
  if (!m.allFinite()) {
    std::ostringstream message;
    message << what << " is not finite:\n" << m;
    throw Error(message.str());
  }
  const Eigen::Matrix3d R = X.linear();
  const double orthonormality = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  const double determinant = R.determinant();
  if (orthonormality > 1e-6 || std::abs(determinant - 1) > 1e-6) {
    std::ostringstream message;
    message << what << " is not a rigid transform: its rotation has |R^T R - I| = " << orthonormality
            << " and det(R) = " << determinant << " (both must be within 1e-6 of a rotation)";
    throw Error(message.str());
  }
}

}  // namespace cfl


// The query compiled twice. Everything the search calls from a header (Eigen, the standard library, cfl's own
// headers) is declared above, before the target pragma: GCC compiles a function for the target in force where
// it is declared, so the header functions the x86-64-v3 copy does not inline stay baseline code, and the
// linker, which keeps one copy of each such function for the whole program, never picks one that needs
// AVX2. Only what the two includes below define, in namespaces of their own, is compiled for x86-64-v3; and
// Eigen, configured before the pragma, keeps its 16-byte alignment (FCL's and the caller's Isometry3d).
// On wuson at 2% of the diagonal the x86-64-v3 copy runs 13.5% fewer instructions per query (211,793 to
// 183,132; cachegrind, 100 poses) and took 0.954 (wuson) and 0.944 (bunny) of the baseline's time (median
// ratio of 30 paired rounds, one FCL query before each CFL query). With fused multiply-adds it ran 18.0%
// fewer instructions and 0.901 / 0.930 of the time, but its results would then differ from the baseline's
// in the last bits (so from one machine to another), and the exact arithmetic of the triangle kernels
// (detail/exact_arithmetic.h) needs products rounded as written.
#if defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 11 && defined(__x86_64__) && !defined(__AVX2__)
#define CFL_X86_64_V3_KERNELS 1
#else
#define CFL_X86_64_V3_KERNELS 0
#endif

namespace cfl {

namespace generic_kernels {
namespace {
#include "detail/distance_search.inc"
}  // namespace
}  // namespace generic_kernels

#if CFL_X86_64_V3_KERNELS
#pragma GCC push_options
#pragma GCC target("arch=x86-64-v3")
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"  // segmentSegmentSquaredDistance: the search needs no copy
namespace x86_64_v3_kernels {
namespace {
#include "detail/triangle_distance_kernels.inc"
#include "detail/distance_search.inc"
}  // namespace
}  // namespace x86_64_v3_kernels
#pragma GCC diagnostic pop
#pragma GCC pop_options
#endif

namespace {

// One build's entry points.
struct KernelTable {
  QueryKernels kernels;
  decltype(&generic_kernels::distanceImpl) distance;
  decltype(&generic_kernels::cachedDistanceImpl) cached_distance;
  decltype(&generic_kernels::bruteForceImpl) brute_force;
  decltype(&generic_kernels::collisionImpl) collision;
};

constexpr KernelTable kGenericTable{QueryKernels::kGeneric, &generic_kernels::distanceImpl,
                                    &generic_kernels::cachedDistanceImpl, &generic_kernels::bruteForceImpl,
                                    &generic_kernels::collisionImpl};
#if CFL_X86_64_V3_KERNELS
constexpr KernelTable kX86_64_V3Table{QueryKernels::kX86_64_V3, &x86_64_v3_kernels::distanceImpl,
                                      &x86_64_v3_kernels::cachedDistanceImpl, &x86_64_v3_kernels::bruteForceImpl,
                                      &x86_64_v3_kernels::collisionImpl};
#endif

// The build's table, or null when this library lacks it or this CPU cannot run it.
const KernelTable* availableTable(QueryKernels kernels) {
  switch (kernels) {
    case QueryKernels::kGeneric:
      return &kGenericTable;
    case QueryKernels::kX86_64_V3:
#if CFL_X86_64_V3_KERNELS
      // libgcc's check covers the operating system too: AVX2 counts only where the kernel saves the YMM
      // registers (XGETBV).
      __builtin_cpu_init();
      if (__builtin_cpu_supports("x86-64-v3")) return &kX86_64_V3Table;
#endif
      return nullptr;
  }
  return nullptr;
}

std::string unavailableMessage(QueryKernels kernels) {
  std::string message = std::string("cfl query kernels '") + queryKernelsName(kernels) + "' are not available: ";
#if CFL_X86_64_V3_KERNELS
  message += "this CPU does not run x86-64-v3 (AVX2, BMI2, FMA, F16C, LZCNT, MOVBE)";
#else
  message += "this build of cfl has no x86-64-v3 copy of the query (it needs GCC 11 or later on x86-64)";
#endif
  return message;
}

const KernelTable& tableFromEnvironment() {
  const char* value = std::getenv("CFL_KERNELS");
  if (value == nullptr || *value == '\0' || std::strcmp(value, "auto") == 0) {
    const KernelTable* best = availableTable(QueryKernels::kX86_64_V3);
    return best != nullptr ? *best : kGenericTable;
  }
  for (QueryKernels kernels : {QueryKernels::kGeneric, QueryKernels::kX86_64_V3}) {
    if (std::strcmp(value, queryKernelsName(kernels)) != 0) continue;
    const KernelTable* table = availableTable(kernels);
    if (table == nullptr) throw Error("CFL_KERNELS=" + std::string(value) + ": " + unavailableMessage(kernels));
    return *table;
  }
  throw Error("CFL_KERNELS=" + std::string(value) + ": expected auto, generic or x86-64-v3");
}

std::atomic<const KernelTable*> active_table{nullptr};

// Read on every query: one load, then the call through the table.
const KernelTable& activeTable() {
  if (const KernelTable* table = active_table.load(std::memory_order_acquire)) return *table;
  // A static's initializer that throws runs again at the next call: a bad CFL_KERNELS fails every query.
  static const KernelTable& chosen = tableFromEnvironment();
  const KernelTable* expected = nullptr;
  active_table.compare_exchange_strong(expected, &chosen);  // a concurrent setQueryKernels wins
  return *active_table.load(std::memory_order_acquire);
}

}  // namespace

QueryKernels activeQueryKernels() { return activeTable().kernels; }

bool queryKernelsAvailable(QueryKernels kernels) { return availableTable(kernels) != nullptr; }

void setQueryKernels(QueryKernels kernels) {
  const KernelTable* table = availableTable(kernels);
  if (table == nullptr) throw Error(unavailableMessage(kernels));
  active_table.store(table, std::memory_order_release);
}

const char* queryKernelsName(QueryKernels kernels) {
  switch (kernels) {
    case QueryKernels::kGeneric:
      return "generic";
    case QueryKernels::kX86_64_V3:
      return "x86-64-v3";
  }
  return "unknown";
}

DistanceResult computeDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                               const Eigen::Isometry3d& X_WB, const DistanceOptions& options) {
  return activeTable().distance(a, X_WA, b, X_WB, options, nullptr);
}

DistanceResult computeDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const CflModel& b,
                               const Eigen::Isometry3d& X_WB, const DistanceOptions& options) {
  return activeTable().distance(a, X_WA, b.geometry, X_WB, options, &b);
}

DistanceResult computeDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                               const Eigen::Isometry3d& X_WB, DistanceCache& cache, const DistanceOptions& options) {
  return activeTable().cached_distance(a, X_WA, b, X_WB, cache, options);
}

DistanceResult bruteForceDistance(const MeshModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                                  const Eigen::Isometry3d& X_WB) {
  return activeTable().brute_force(a, X_WA, b, X_WB);
}

bool computeCollision(const MeshModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                      const Eigen::Isometry3d& X_WB, std::size_t max_contacts, std::vector<Contact>* contacts) {
  return activeTable().collision(a, X_WA, b, X_WB, max_contacts, contacts);
}

}  // namespace cfl
