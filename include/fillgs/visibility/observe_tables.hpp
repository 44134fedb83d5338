#pragma once
// The observation tables on disk: the compact layout `fillgs observe` writes by default, the
// dense [T, N] layouts one flag away, and the reader every consumer of a folder goes through.
//
// Compact (N Gaussians, M of them moving, T frames):
//   count_static.npy   [R, N]  the static Gaussians' counts, one row per distinct set of
//                              camera poses observing a frame (moving columns hold 0)
//   count_rows.npy     [T]     uint32: the row of count_static each frame starts from
//   count_dynamic.npy  [T, M]  the moving Gaussians' counts (dynamic_ids order)
//   count_change_offsets.npy [T + 1] int64, count_change_ids.npy [E] uint32,
//   count_change_values.npy  [E]: static Gaussians whose count at frame t differs from its
//                              row (a moving Gaussian hides or uncovers them: raytraced and
//                              exact modes), entries offsets[t] to offsets[t + 1]
//   speed_dynamic.npy, deficiency_dynamic.npy [T, M] float32 (static Gaussians: s = D = 0)
// Counts are uint8, or uint16 where more than 255 views share a time. In numpy:
//   C = count_static[count_rows]; C[:, dynamic_ids] = count_dynamic
//   for t in range(T): s = slice(offsets[t], offsets[t + 1]); C[t, change_ids[s]] = change_values[s]
// Dense: count.npy [T, N], speed.npy and deficiency.npy [T, N]; "dynamic": count.npy [T, N]
// with the _dynamic motion tables.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "fillgs/base/names.hpp"
#include "fillgs/io/npy.hpp"
#include "fillgs/model/camera.hpp"

namespace fillgs {

enum class TableLayout { Compact, Dense, Dynamic };
FILLGS_ENUM_NAMES(TableLayout, "table layout", {TableLayout::Compact, "compact"}, {TableLayout::Dense, "dense"},
                  {TableLayout::Dynamic, "dynamic"});

/// The count rows of a compact table are keyed by the multiset of camera poses observing a
/// frame: per time of `times`, the key (numbered in order of first appearance over all
/// `times`, so that every shard of a job numbers them alike). `counted`: one flag per camera
/// (ObservationOptions::cameras), empty for every camera.
std::vector<uint32_t> count_row_keys(const std::vector<Camera>& cameras, const std::vector<double>& times, double frame_step,
                                     const std::vector<uint8_t>& counted);

/// Streams the count tables of the compact layout into a folder, frame by frame. A frame's
/// static columns are compared with its key's row: equal (always so in frustum mode) costs
/// nothing on disk, the others are written as changes. Rows are held in memory only until
/// the last frame of their key. finish() renames every file into place.
class CompactCountWriter {
 public:
  /// `keys`: the key of every frame to be written, in order; `narrow`: uint8 counts.
  CompactCountWriter(const std::string& dir, bool narrow, size_t gaussians, const std::vector<uint32_t>& dynamic_ids,
                     const std::vector<uint32_t>& keys);
  ~CompactCountWriter();
  /// The next frame's counts of every Gaussian.
  void write(const uint16_t* counts);
  void finish();
  /// The files written (relative to the folder), the rows' keys, and the changes.
  std::vector<std::string> files() const;
  const std::vector<uint32_t>& row_keys() const { return row_keys_; }
  uint64_t changes() const { return offsets_.back(); }

 private:
  std::string dir_;
  bool narrow_;
  size_t N_;
  std::vector<uint32_t> dynamic_ids_, keys_, row_keys_, rows_;
  std::vector<uint8_t> moving_;
  std::vector<size_t> last_use_;
  std::map<uint32_t, std::vector<uint16_t>> held_;  ///< key -> its row (moving columns: this frame's)
  std::map<uint32_t, uint32_t> row_of_key_;
  std::vector<int64_t> offsets_;
  // Reused by every frame: a row as written, its narrowed bytes, the frame's changes.
  std::vector<uint16_t> scratch_;
  std::vector<uint8_t> narrowed_;
  std::vector<uint32_t> frame_ids_;
  std::vector<uint16_t> frame_values_;
  std::unique_ptr<NpyStreamWriter> static_, dynamic_, change_ids_, change_values_;
  size_t frame_ = 0;
};

/// An observe folder's tables as written (either layout), read and checked: counts at most
/// the most views of a frame, ids inside the model, rows and offsets consistent, motion
/// values finite and >= 0. Every failure is one line naming the file and the element.
struct ObservationFolder {
  std::string dir;
  TableLayout layout = TableLayout::Compact;
  size_t gaussians = 0;
  bool narrow = true;              ///< counts stored as uint8
  size_t max_views = 0;
  std::vector<uint32_t> dynamic_ids;
  std::vector<double> times;
  // compact
  size_t static_rows = 0;
  std::vector<uint16_t> count_static;   ///< [R, N]
  std::vector<uint32_t> count_rows;     ///< [T]
  std::vector<uint16_t> count_dynamic;  ///< [T, M]
  std::vector<int64_t> change_offsets;  ///< [T + 1]
  std::vector<uint32_t> change_ids;
  std::vector<uint16_t> change_values;
  // dense and dynamic layouts
  std::vector<uint16_t> counts;         ///< [T, N]
  // motion over the moving Gaussians (the dense files' moving columns), [T, M]
  std::vector<float> dynamic_speed, dynamic_deficiency;

  size_t frames() const { return times.size(); }
  /// The counts of every Gaussian at frame `f`, whichever layout.
  void count_row(size_t f, uint16_t* out) const;
};

/// Reads `dir` (summary.json says the layout; a folder written before the key existed is
/// dense or dynamic by its files).
ObservationFolder read_observation(const std::string& dir);

}  // namespace fillgs
