// A shared library holding cfl_fcl (linked in statically), standing for a user's own library, e.g. a
// planning plugin. wrong_link_order_test links it AFTER libfcl, the configuration that bypasses the adapter.
#include "cfl_fcl/cfl_geometry.h"

#include <string>

// Constructs a small CFL geometry; returns the cfl::Error message, or "" when construction succeeded.
extern "C" const char* cflFclHelperConstructGeometry() {
  static std::string message;
  try {
    const std::vector<fcl::Vector3d> v = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const std::vector<fcl::Triangle> t = {fcl::Triangle(0, 1, 2), fcl::Triangle(0, 1, 3), fcl::Triangle(0, 2, 3),
                                          fcl::Triangle(1, 2, 3)};
    cfl::BuildOptions options;
    options.resolution = 8;
    cfl_fcl::CFLGeometry geometry(v, t, options);
    message.clear();
  } catch (const cfl::Error& e) {
    message = e.what();
  }
  return message.c_str();
}
