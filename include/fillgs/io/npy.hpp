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

/// As read_npy, from bytes held in memory (an .npz entry); `source` names them in errors.
NpyArray parse_npy(const std::string& bytes, const std::string& source);

/// Writes a C-order array atomically. T: float, double, uint8_t, uint16_t, uint32_t, int32_t, int64_t.
template <typename T>
void write_npy(const std::string& path, const T* data, const std::vector<size_t>& shape);

/// Writes a C-order array row by row, for tables too large to hold: the header is written
/// first (the shape is known), rows are appended, and finish() checks the byte count and
/// renames the temporary file over `path`. Destroyed unfinished, it removes the temporary.
class NpyStreamWriter {
 public:
  NpyStreamWriter(const std::string& path, const std::string& descr, size_t item_bytes, const std::vector<size_t>& shape);
  /// A writer whose first dimension is the number of rows written (each `row_shape` wide,
  /// `{}` for a 1-D array): the header is reserved for the largest count and rewritten by
  /// finish() with the count, padded with spaces to the same length (as numpy pads).
  static NpyStreamWriter growing(const std::string& path, const std::string& descr, size_t item_bytes, const std::vector<size_t>& row_shape);
  NpyStreamWriter(NpyStreamWriter&& other) noexcept;
  ~NpyStreamWriter();
  NpyStreamWriter(const NpyStreamWriter&) = delete;
  NpyStreamWriter& operator=(const NpyStreamWriter&) = delete;
  void write(const void* data, size_t bytes);
  void finish();
  const std::string& path() const { return path_; }

 private:
  NpyStreamWriter() = default;
  std::string path_, tmp_, descr_;
  void* file_ = nullptr;
  size_t expected_ = 0, written_ = 0;
  // growing(): bytes per row, the rows' shape and the header's reserved length (0: fixed shape)
  size_t row_bytes_ = 0, header_bytes_ = 0;
  std::vector<size_t> row_shape_;
};

/// The .npy header (magic, version 1.0, padded dict) for a C-order array; with `length`, the
/// dict is padded to make the header exactly that long (at least its natural length).
std::string npy_header(const std::string& descr, const std::vector<size_t>& shape, size_t length = 0);

/// numpy descr string of T ("<f4", "|u1", ...).
template <typename T>
const char* npy_descr();

}  // namespace fillgs
