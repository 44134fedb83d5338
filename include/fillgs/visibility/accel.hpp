#pragma once
// The narrow interface of fillgs_accel, the only code that sees Embree and OpenVDB.
// (The visibility engine and the exploration grid build on the owners declared in
// accel/embree_device.hpp and accel/vdb_init.cpp.)
#include <string>

namespace fillgs::accel {

struct AccelInfo {
  std::string embree_version;   ///< as reported by a live Embree device
  std::string openvdb_version;  ///< as compiled and initialised
};

/// Creates an Embree device (with its error callback) and initialises OpenVDB; throws
/// fillgs::Error with Embree's message if the device cannot be created.
AccelInfo accel_info();

}  // namespace fillgs::accel
