#include "embree_device.hpp"

#include <string>

#include "fillgs/visibility/accel.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/instruction_set.hpp"

namespace fillgs::accel {

EmbreeDevice::EmbreeDevice(const char* config) {
  // Without a configuration of its own, the device keeps to FILLGS_INSTRUCTION_SET's cap.
  const std::string capped = embree_device_config();
  device_ = rtcNewDevice(config ? config : capped.empty() ? nullptr : capped.c_str());
  if (!device_) throw_error("Embree: cannot create a device (error ", int(rtcGetDeviceError(nullptr)), ")");
  rtcSetDeviceErrorFunction(device_, &EmbreeDevice::on_error, this);
}

EmbreeDevice::~EmbreeDevice() {
  if (device_) rtcReleaseDevice(device_);
}

void EmbreeDevice::on_error(void* user, RTCError code, const char* message) {
  // Runs inside Embree: record, never throw.
  auto* self = static_cast<EmbreeDevice*>(user);
  std::lock_guard<std::mutex> lock(self->mutex_);
  if (self->first_error_.empty())
    self->first_error_ = "Embree error " + std::to_string(int(code)) + ": " + (message ? message : "");
}

void EmbreeDevice::check(const char* where) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (first_error_.empty()) return;
  std::string e;
  e.swap(first_error_);
  throw_error(where, ": ", e);
}

std::string openvdb_version_string();

AccelInfo accel_info() {
  EmbreeDevice device;
  AccelInfo info;
  const ssize_t v = rtcGetDeviceProperty(device.get(), RTC_DEVICE_PROPERTY_VERSION);
  info.embree_version = std::to_string(v / 10000) + "." + std::to_string((v / 100) % 100) + "." + std::to_string(v % 100);
  device.check("Embree device query");
  info.openvdb_version = openvdb_version_string();
  return info;
}

}  // namespace fillgs::accel
