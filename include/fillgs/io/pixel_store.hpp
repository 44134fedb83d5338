#pragma once
// The 8-bit images of a dataset: held in memory, or — when they add up to more than a byte
// budget — in an unlinked temporary file written once while loading and read back per image
// on demand (pread), so a video larger than the machine's memory still trains. The file
// disappears with the process, even when it is killed; the page cache keeps what is read
// often. Filled once (put, thread-safe for distinct images), then read-only (get, thread-safe).
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace fillgs {

class PixelStore {
 public:
  /// Images of `sizes[i]` bytes; spilled to a file in `spill_dir` (empty: the system's
  /// temporary folder, $TMPDIR) when their sum exceeds `budget` bytes.
  void reset(const std::vector<size_t>& sizes, size_t budget, const std::string& spill_dir = "");
  void put(size_t i, std::vector<uint8_t>&& pixels);
  /// Image i: the one held in memory, or read from the file into `scratch` (and returned).
  const std::vector<uint8_t>& get(size_t i, std::vector<uint8_t>& scratch) const;
  /// Image i handed over: moved out of memory (the store no longer holds it), or read from the file.
  std::vector<uint8_t> take(size_t i);
  size_t bytes() const { return total_; }
  bool spilled() const { return file_ != nullptr; }

 private:
  struct File;
  std::vector<size_t> sizes_, offsets_;
  size_t total_ = 0;
  std::vector<std::vector<uint8_t>> memory_;
  std::shared_ptr<File> file_;  ///< shared by copies of a dataset: read-only once filled
};

/// The default budget for a dataset's images: a quarter of this machine's physical memory.
size_t default_image_budget();

}  // namespace fillgs
