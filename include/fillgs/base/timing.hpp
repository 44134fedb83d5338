#pragma once
// Wall-clock timing of phases (steady clock).
#include <chrono>

namespace fillgs {

using Clock = std::chrono::steady_clock;

/// Seconds since `start`.
inline double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

}  // namespace fillgs
