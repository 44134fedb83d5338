#pragma once
// RAII owner of an Embree device whose error callback is set the moment it is created,
// so no later call needs its own check: errors are recorded and raised by check().
#include <embree3/rtcore.h>

#include <mutex>
#include <string>

namespace fillgs::accel {

class EmbreeDevice {
 public:
  explicit EmbreeDevice(const char* config = nullptr);
  ~EmbreeDevice();
  EmbreeDevice(const EmbreeDevice&) = delete;
  EmbreeDevice& operator=(const EmbreeDevice&) = delete;

  RTCDevice get() const { return device_; }
  /// Throws fillgs::Error with the first error Embree reported since the last check.
  void check(const char* where) const;

 private:
  static void on_error(void* user, RTCError code, const char* message);
  RTCDevice device_ = nullptr;
  mutable std::mutex mutex_;
  mutable std::string first_error_;
};

}  // namespace fillgs::accel
