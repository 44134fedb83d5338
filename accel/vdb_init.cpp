#include <openvdb/openvdb.h>

#include <string>

namespace fillgs::accel {

std::string openvdb_version_string() {
  openvdb::initialize();  // idempotent; registers grid types for I/O
  return std::to_string(openvdb::OPENVDB_LIBRARY_MAJOR_VERSION) + "." +
         std::to_string(openvdb::OPENVDB_LIBRARY_MINOR_VERSION) + "." +
         std::to_string(openvdb::OPENVDB_LIBRARY_PATCH_VERSION);
}

}  // namespace fillgs::accel
