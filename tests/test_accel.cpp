// fillgs_accel is linked against the Embree 3 and OpenVDB the build found.
#include "fillgs/visibility/accel.hpp"
#include "helpers.hpp"

TEST_CASE("Embree 3.13 device and OpenVDB 10 initialise", "[accel]") {
  const fillgs::accel::AccelInfo info = fillgs::accel::accel_info();
  CHECK(info.embree_version.rfind("3.13.", 0) == 0);
  CHECK(info.openvdb_version.rfind("10.", 0) == 0);
}
