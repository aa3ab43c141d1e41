#pragma once
// The reference for every adapter test: libfcl's own fcl::distance<double> / fcl::collide<double>, called
// through dlsym on libfcl.so itself. In these test programs the names fcl::distance / fcl::collide are the
// adapter's (that is what is under test), so calling them would not be an independent reference.

#include <fcl/fcl.h>

#include <dlfcn.h>
#include <link.h>

#include <cstring>
#include <stdexcept>
#include <string>

namespace cfl_fcl::test {

struct PlainFcl {
  double (*distance_objects)(const fcl::CollisionObjectd*, const fcl::CollisionObjectd*,
                             const fcl::DistanceRequestd&, fcl::DistanceResultd&) = nullptr;
  double (*distance_geometries)(const fcl::CollisionGeometryd*, const fcl::Transform3d&,
                                const fcl::CollisionGeometryd*, const fcl::Transform3d&,
                                const fcl::DistanceRequestd&, fcl::DistanceResultd&) = nullptr;
  std::size_t (*collide_objects)(const fcl::CollisionObjectd*, const fcl::CollisionObjectd*,
                                 const fcl::CollisionRequestd&, fcl::CollisionResultd&) = nullptr;
  std::size_t (*collide_geometries)(const fcl::CollisionGeometryd*, const fcl::Transform3d&,
                                    const fcl::CollisionGeometryd*, const fcl::Transform3d&,
                                    const fcl::CollisionRequestd&, fcl::CollisionResultd&) = nullptr;
};

inline const PlainFcl& plainFcl() {
  static const PlainFcl fcl_own = [] {
    std::string path;
    dl_iterate_phdr(
        [](dl_phdr_info* info, size_t, void* data) {
          if (info->dlpi_name && std::strstr(info->dlpi_name, "libfcl.so")) {
            *static_cast<std::string*>(data) = info->dlpi_name;
            return 1;
          }
          return 0;
        },
        &path);
    void* handle = path.empty() ? nullptr : dlopen(path.c_str(), RTLD_LAZY | RTLD_NOLOAD);
    if (handle == nullptr) throw std::runtime_error("test: libfcl.so is not loaded");
    PlainFcl p;
    p.distance_objects = reinterpret_cast<decltype(p.distance_objects)>(dlsym(
        handle,
        "_ZN3fcl8distanceIdEET_PKNS_15CollisionObjectIS1_EES5_RKNS_15DistanceRequestIS1_EERNS_14DistanceResultIS1_EE"));
    p.distance_geometries = reinterpret_cast<decltype(p.distance_geometries)>(
        dlsym(handle,
              "_ZN3fcl8distanceIdEET_PKNS_17CollisionGeometryIS1_EERKN5Eigen9TransformIS1_Li3ELi1ELi0EEES5_SA_RKNS_"
              "15DistanceRequestIS1_EERNS_14DistanceResultIS1_EE"));
    p.collide_objects = reinterpret_cast<decltype(p.collide_objects)>(dlsym(
        handle,
        "_ZN3fcl7collideIdEEmPKNS_15CollisionObjectIT_EES5_RKNS_16CollisionRequestIS2_EERNS_15CollisionResultIS2_EE"));
    p.collide_geometries = reinterpret_cast<decltype(p.collide_geometries)>(
        dlsym(handle,
              "_ZN3fcl7collideIdEEmPKNS_17CollisionGeometryIT_EERKN5Eigen9TransformIS2_Li3ELi1ELi0EEES5_SA_RKNS_"
              "16CollisionRequestIS2_EERNS_15CollisionResultIS2_EE"));
    if (!p.distance_objects || !p.distance_geometries || !p.collide_objects || !p.collide_geometries)
      throw std::runtime_error("test: libfcl.so lacks fcl::distance<double>/fcl::collide<double>");
    return p;
  }();
  return fcl_own;
}

}  // namespace cfl_fcl::test
