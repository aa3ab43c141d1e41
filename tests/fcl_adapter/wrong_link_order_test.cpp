// Linked as `fcl` first, then a shared library holding cfl_fcl: libfcl's fcl::distance / fcl::collide come
// first in symbol lookup, so calls would never reach the adapter. The adapter must say so, loudly, at the
// first CFL geometry, instead of letting fcl::distance print "not supported" and return DBL_MAX.
#include "plain_fcl.h"

#include <fcl/fcl.h>

#include <gtest/gtest.h>

#include <string>

extern "C" const char* cflFclHelperConstructGeometry();

namespace {

TEST(FclAdapterLinkOrder, PremiseLibfclDefinitionsComeFirstInThisProgram) {
  // Without this, the test below would not be testing the bypassed configuration.
  using Fn = double (*)(const fcl::CollisionObjectd*, const fcl::CollisionObjectd*, const fcl::DistanceRequestd&,
                        fcl::DistanceResultd&);
  const Fn resolved = &fcl::distance<double>;
  EXPECT_EQ(reinterpret_cast<const void*>(resolved),
            reinterpret_cast<const void*>(cfl_fcl::test::plainFcl().distance_objects));
}

TEST(FclAdapterLinkOrder, SharedLibraryLinkedAfterLibfclFailsAtFirstGeometryWithTheFix) {
  const std::string message = cflFclHelperConstructGeometry();
  ASSERT_FALSE(message.empty()) << "constructing a CFL geometry succeeded although fcl::distance bypasses it";
  EXPECT_NE(message.find("fcl::distance"), std::string::npos) << message;
  EXPECT_NE(message.find("fcl::collide"), std::string::npos) << message;
  EXPECT_NE(message.find("must come before libfcl"), std::string::npos) << message;
  EXPECT_NE(message.find("target_link_libraries"), std::string::npos) << message;
  EXPECT_NE(message.find("libcfl_fcl_link_order_helper"), std::string::npos) << "names the library: " << message;
  // Every later geometry fails the same way (the verdict is per process).
  EXPECT_EQ(std::string(cflFclHelperConstructGeometry()), message);
}

}  // namespace
