// The public queries: each picks the kernel table of the instruction set that activeQueryKernels names
// (detail/query_kernels.h) and runs the search (distance_search.cpp) with it.

#include "detail/distance_search.h"
#include "detail/query_kernels.h"

#include <atomic>
#include <cstdlib>
#include <cstring>

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

namespace {

// The instruction set's table, or null when this library lacks it or this CPU cannot run it.
const detail::QueryKernelTable* availableTable(QueryKernels kernels) {
  switch (kernels) {
    case QueryKernels::kGeneric:
      return &detail::kGenericQueryKernels;
    case QueryKernels::kX86_64_V3:
#if CFL_X86_64_V3_KERNELS
      // libgcc's check covers the operating system too: AVX2 counts only where the kernel saves the YMM
      // registers (XGETBV).
      __builtin_cpu_init();
      if (__builtin_cpu_supports("x86-64-v3")) return &detail::kX86_64_V3QueryKernels;
#endif
      return nullptr;
  }
  return nullptr;
}

std::string unavailableMessage(QueryKernels kernels) {
  if (kernels != QueryKernels::kGeneric && kernels != QueryKernels::kX86_64_V3) {
    return "QueryKernels value " + std::to_string(static_cast<int>(kernels)) + " names no kernel set of the cfl query";
  }
  std::string message = std::string("cfl query kernels '") + queryKernelsName(kernels) + "' are not available: ";
#if CFL_X86_64_V3_KERNELS
  message += "this CPU does not run x86-64-v3 (AVX2, BMI2, FMA, F16C, LZCNT, MOVBE)";
#else
  message += "this build of cfl has no x86-64-v3 kernels (they need GCC 12 or later on x86-64)";
#endif
  return message;
}

const detail::QueryKernelTable& tableFromEnvironment() {
  const char* value = std::getenv("CFL_KERNELS");
  if (value == nullptr || *value == '\0' || std::strcmp(value, "auto") == 0) {
    const detail::QueryKernelTable* best = availableTable(QueryKernels::kX86_64_V3);
    return best != nullptr ? *best : detail::kGenericQueryKernels;
  }
  for (QueryKernels kernels : {QueryKernels::kGeneric, QueryKernels::kX86_64_V3}) {
    if (std::strcmp(value, queryKernelsName(kernels)) != 0) continue;
    const detail::QueryKernelTable* table = availableTable(kernels);
    if (table == nullptr) throw Error("CFL_KERNELS=" + std::string(value) + ": " + unavailableMessage(kernels));
    return *table;
  }
  throw Error("CFL_KERNELS=" + std::string(value) + ": expected auto, generic or x86-64-v3");
}

std::atomic<const detail::QueryKernelTable*> active_table{nullptr};

}  // namespace

// Read on every query: one load.
const detail::QueryKernelTable& detail::activeQueryKernelTable() {
  if (const detail::QueryKernelTable* table = active_table.load(std::memory_order_acquire)) return *table;
  // A static's initializer that throws runs again at the next call: a bad CFL_KERNELS fails every query.
  static const detail::QueryKernelTable& chosen = tableFromEnvironment();
  const detail::QueryKernelTable* expected = nullptr;
  active_table.compare_exchange_strong(expected, &chosen);  // a concurrent setQueryKernels wins
  return *active_table.load(std::memory_order_acquire);
}

QueryKernels activeQueryKernels() { return detail::activeQueryKernelTable().kernels; }

bool queryKernelsAvailable(QueryKernels kernels) { return availableTable(kernels) != nullptr; }

void setQueryKernels(QueryKernels kernels) {
  const detail::QueryKernelTable* table = availableTable(kernels);
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
  return detail::distanceImpl(detail::activeQueryKernelTable(), a, X_WA, b, X_WB, options, nullptr);
}

DistanceResult computeDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const CflModel& b,
                               const Eigen::Isometry3d& X_WB, const DistanceOptions& options) {
  return detail::distanceImpl(detail::activeQueryKernelTable(), a, X_WA, b.geometry, X_WB, options, &b);
}

DistanceResult computeDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                               const Eigen::Isometry3d& X_WB, DistanceCache& cache, const DistanceOptions& options) {
  return detail::cachedDistanceImpl(detail::activeQueryKernelTable(), a, X_WA, b, X_WB, cache, options);
}

DistanceResult bruteForceDistance(const MeshModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                                  const Eigen::Isometry3d& X_WB) {
  return detail::bruteForceImpl(detail::activeQueryKernelTable(), a, X_WA, b, X_WB);
}

bool computeCollision(const MeshModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                      const Eigen::Isometry3d& X_WB, std::size_t max_contacts, std::vector<Contact>* contacts) {
  return detail::collisionImpl(detail::activeQueryKernelTable(), a, X_WA, b, X_WB, max_contacts, contacts);
}

}  // namespace cfl
