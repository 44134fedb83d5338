#pragma once
// NumPy .npy reading and writing (format versions 1.0-3.0, C or Fortran order).
#include <cstdint>
#include <string>
#include <vector>

namespace fillgs {

struct NpyArray {
  std::string descr;          ///< e.g. "<f8", "<u2"
  std::vector<size_t> shape;
  bool fortran_order = false;
  std::string bytes;          ///< raw payload as stored
  size_t size() const;        ///< element count
  /// Every element converted to double, in C (row-major) order.
  std::vector<double> to_doubles(const std::string& source) const;
};

NpyArray read_npy(const std::string& path);

/// Writes a C-order array atomically. T: float, double, uint8_t, uint16_t, uint32_t, int32_t, int64_t.
template <typename T>
void write_npy(const std::string& path, const T* data, const std::vector<size_t>& shape);

/// numpy descr string of T ("<f4", "|u1", ...).
template <typename T>
const char* npy_descr();

}  // namespace fillgs
