#pragma once
// Stateless seeded random numbers (SplitMix64 of the arguments): the same draw whatever the
// order, thread or resumption, so that interrupted runs draw what uninterrupted ones would.
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace fillgs {

inline uint64_t mix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
/// Uniform in [0, 1) from three keys.
inline double uniform(uint64_t a, uint64_t b, uint64_t c) {
  return double(mix64(mix64(mix64(a) ^ b) ^ c) >> 11) * (1.0 / 9007199254740992.0);
}
/// Standard normal (Box–Muller) from three keys.
inline double normal(uint64_t a, uint64_t b, uint64_t c) {
  const double u1 = std::max(uniform(a, b, 2 * c), 1e-300), u2 = uniform(a, b, 2 * c + 1);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * 3.14159265358979323846 * u2);
}
/// A 64-bit key of a string (FNV-1a), to seed draws by name.
inline uint64_t string_key(const char* s) {
  uint64_t h = 1469598103934665603ull;
  for (; *s; ++s) h = (h ^ uint64_t(uint8_t(*s))) * 1099511628211ull;
  return h;
}

}  // namespace fillgs
