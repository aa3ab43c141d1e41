#pragma once
/// @file
/// libfcl.so's own fcl::distance, for the benchmarks that link the FCL adapter. The adapter defines
/// fcl::distance<double> itself (fcl_adapter/fcl_entry_points.cpp: pairs with a CFL geometry answered by cfl,
/// the rest handed to libfcl), so in such a program the name fcl::distance is the adapter's; timing what a
/// plain FCL program runs takes the library's symbol, looked up by hand. Needs ${CMAKE_DL_LIBS}.

#include <fcl/fcl.h>

#include <dlfcn.h>
#include <link.h>

#include <cstring>
#include <stdexcept>
#include <string>

namespace cfl::bench {

/// fcl::distance<double>(const CollisionObject*, const CollisionObject*, const DistanceRequest&,
/// DistanceResult&).
using DistanceObjectsFn = double (*)(const fcl::CollisionObjectd*, const fcl::CollisionObjectd*,
                                     const fcl::DistanceRequestd&, fcl::DistanceResultd&);

/// The overload above as libfcl.so 0.7 exports it; throws std::runtime_error when the loaded libfcl.so does
/// not export it (another FCL version, or FCL linked statically).
inline DistanceObjectsFn libfclDistance() {
  std::string path;
  dl_iterate_phdr(
      [](dl_phdr_info* info, size_t, void* data) {
        if (info->dlpi_name == nullptr || std::strstr(info->dlpi_name, "libfcl.so") == nullptr) return 0;
        *static_cast<std::string*>(data) = info->dlpi_name;
        return 1;
      },
      &path);
  void* handle = path.empty() ? nullptr : dlopen(path.c_str(), RTLD_LAZY | RTLD_NOLOAD);
  void* symbol = handle == nullptr ? nullptr
                                   : dlsym(handle,
                                           "_ZN3fcl8distanceIdEET_PKNS_15CollisionObjectIS1_EES5_RKNS_"
                                           "15DistanceRequestIS1_EERNS_14DistanceResultIS1_EE");
  if (symbol == nullptr) throw std::runtime_error("cannot find libfcl.so's own fcl::distance<double>");
  return reinterpret_cast<DistanceObjectsFn>(symbol);
}

}  // namespace cfl::bench
