#include "fillgs/visibility/observe_tables.hpp"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <type_traits>

#include <nlohmann/json.hpp>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/json_file.hpp"
#include "fillgs/visibility/visibility.hpp"

namespace fillgs {

std::vector<uint32_t> count_row_keys(const std::vector<Camera>& cameras, const std::vector<double>& times, double frame_step,
                                     const std::vector<uint8_t>& counted) {
  size_t poses = 0;
  const std::vector<uint32_t> pose = camera_pose_groups(cameras, &poses);
  std::map<std::vector<uint32_t>, uint32_t> numbered;
  std::vector<uint32_t> keys;
  for (const std::vector<uint32_t>& views : views_per_frame(cameras, times, frame_step)) {
    std::vector<uint32_t> set;
    for (uint32_t c : views)
      if (counted.empty() || counted[c]) set.push_back(pose[c]);
    std::sort(set.begin(), set.end());
    keys.push_back(numbered.try_emplace(std::move(set), uint32_t(numbered.size())).first->second);
  }
  return keys;
}

namespace {

const char* count_descr(bool narrow) { return narrow ? "|u1" : "<u2"; }

/// Writes `n` counts as the table's type (uint8 or uint16).
void write_counts(NpyStreamWriter& out, bool narrow, const uint16_t* counts, size_t n, std::vector<uint8_t>& narrowed) {
  if (!narrow) {
    out.write(counts, n * 2);
    return;
  }
  narrowed.assign(counts, counts + n);
  out.write(narrowed.data(), n);
}

}  // namespace

CompactCountWriter::CompactCountWriter(const std::string& dir, bool narrow, size_t gaussians, const std::vector<uint32_t>& dynamic_ids,
                                       const std::vector<uint32_t>& keys)
    : dir_(dir), narrow_(narrow), N_(gaussians), dynamic_ids_(dynamic_ids), keys_(keys), moving_(gaussians, 0), offsets_{0} {
  for (uint32_t g : dynamic_ids_) moving_[g] = 1;
  std::map<uint32_t, size_t> last;
  for (size_t f = 0; f < keys_.size(); ++f) last[keys_[f]] = f;
  last_use_.resize(keys_.size());
  for (size_t f = 0; f < keys_.size(); ++f) last_use_[f] = last[keys_[f]];
  const size_t R = last.size(), M = dynamic_ids_.size();
  static_ = std::make_unique<NpyStreamWriter>(join_path(dir, "count_static.npy"), count_descr(narrow), narrow ? 1 : 2, std::vector<size_t>{R, N_});
  dynamic_ = std::make_unique<NpyStreamWriter>(join_path(dir, "count_dynamic.npy"), count_descr(narrow), narrow ? 1 : 2,
                                               std::vector<size_t>{keys_.size(), M});
  change_ids_ = std::make_unique<NpyStreamWriter>(NpyStreamWriter::growing(join_path(dir, "count_change_ids.npy"), "<u4", 4, {}));
  change_values_ =
      std::make_unique<NpyStreamWriter>(NpyStreamWriter::growing(join_path(dir, "count_change_values.npy"), count_descr(narrow), narrow ? 1 : 2, {}));
}

CompactCountWriter::~CompactCountWriter() = default;

void CompactCountWriter::write(const uint16_t* counts) {
  FILLGS_CHECK(frame_ < keys_.size());
  const uint32_t key = keys_[frame_];
  const auto [at, fresh] = row_of_key_.try_emplace(key, uint32_t(row_keys_.size()));
  frame_ids_.clear();
  frame_values_.clear();
  if (fresh) {
    row_keys_.push_back(key);
    scratch_.assign(counts, counts + N_);
    for (uint32_t g : dynamic_ids_) scratch_[g] = 0;
    write_counts(*static_, narrow_, scratch_.data(), N_, narrowed_);
    if (last_use_[frame_] > frame_) held_[key].assign(counts, counts + N_);
  } else {
    std::vector<uint16_t>& row = held_.at(key);
    for (uint32_t g : dynamic_ids_) row[g] = counts[g];  // the moving columns are not compared
    constexpr size_t kBlock = 2048;
    for (size_t b = 0; b < N_; b += kBlock) {
      const size_t n = std::min(kBlock, N_ - b);
      if (std::memcmp(counts + b, row.data() + b, n * sizeof(uint16_t)) == 0) continue;
      for (size_t g = b; g < b + n; ++g)
        if (counts[g] != row[g]) {
          frame_ids_.push_back(uint32_t(g));
          frame_values_.push_back(counts[g]);
        }
    }
  }
  rows_.push_back(at->second);
  scratch_.resize(dynamic_ids_.size());
  for (size_t j = 0; j < dynamic_ids_.size(); ++j) scratch_[j] = counts[dynamic_ids_[j]];
  write_counts(*dynamic_, narrow_, scratch_.data(), scratch_.size(), narrowed_);
  change_ids_->write(frame_ids_.data(), frame_ids_.size() * 4);
  write_counts(*change_values_, narrow_, frame_values_.data(), frame_values_.size(), narrowed_);
  offsets_.push_back(offsets_.back() + int64_t(frame_ids_.size()));
  if (last_use_[frame_] == frame_) held_.erase(key);
  ++frame_;
}

void CompactCountWriter::finish() {
  FILLGS_CHECK(frame_ == keys_.size());
  static_->finish();
  dynamic_->finish();
  change_ids_->finish();
  change_values_->finish();
  write_npy(join_path(dir_, "count_rows.npy"), rows_.data(), {rows_.size()});
  write_npy(join_path(dir_, "count_change_offsets.npy"), offsets_.data(), {offsets_.size()});
}

std::vector<std::string> CompactCountWriter::files() const {
  return {"count_static.npy", "count_rows.npy", "count_dynamic.npy", "count_change_offsets.npy", "count_change_ids.npy", "count_change_values.npy"};
}

// ------------------------------------------------------------------ reading

namespace {

/// One table of the folder: its file, checked against the expected dtype and shape
/// (`rows` 0 in `shape` means any row count), as values of type T.
template <typename T>
std::vector<T> read_table(const std::string& dir, const std::string& name, const std::string& descr, std::vector<size_t> shape) {
  const std::string path = join_path(dir, name);
  if (!std::filesystem::exists(path)) throw_error(path, ": missing (the folder's summary.json names this table layout)");
  const NpyArray a = read_npy(path);
  auto text = [](const std::vector<size_t>& s) {
    std::string t = "[";
    for (size_t i = 0; i < s.size(); ++i) t += (i ? ", " : "") + std::to_string(s[i]);
    return t + "]";
  };
  if (a.descr != descr || a.fortran_order || a.shape.size() != shape.size())
    throw_error(path, ": ", a.descr, " ", text(a.shape), ", expected ", descr, " ", text(shape), " in C order");
  for (size_t d = 0; d < shape.size(); ++d)
    if (a.shape[d] != shape[d]) throw_error(path, ": shape ", text(a.shape), ", expected ", text(shape));
  std::vector<T> out(a.size());
  if (descr == "|u1") {
    for (size_t i = 0; i < out.size(); ++i) out[i] = T(static_cast<unsigned char>(a.bytes[i]));
  } else {
    FILLGS_CHECK(a.bytes.size() == out.size() * sizeof(T));
    if (!out.empty()) std::memcpy(out.data(), a.bytes.data(), a.bytes.size());
  }
  return out;
}

size_t rows_of(const std::string& dir, const std::string& name) {
  const NpyArray a = read_npy(join_path(dir, name));
  if (a.shape.empty()) throw_error(join_path(dir, name), ": a scalar, expected a table");
  return a.shape[0];
}

/// The element as "[row, column]" for a table `width` wide, else its index.
std::string element(size_t i, size_t width) {
  return width ? "[" + std::to_string(i / width) + ", " + std::to_string(i % width) + "]" : std::to_string(i);
}

template <typename T>
void check_at_most(const std::string& dir, const std::string& name, const std::vector<T>& v, double max, size_t width) {
  for (size_t i = 0; i < v.size(); ++i) {
    const double x = double(v[i]);
    if (!(x >= 0 && x <= max))
      throw_error(join_path(dir, name), ": element ", element(i, width), " is ", x, ", outside [0, ", max, "]",
                  std::is_floating_point_v<T> ? " (not a finite speed or deficiency)" : "");
  }
}

/// The moving columns of a dense [T, N] motion table, checked: finite, >= 0, and 0 for static Gaussians.
std::vector<float> moving_columns(const std::string& dir, const std::string& name, const std::vector<float>& dense, size_t N,
                                  const std::vector<uint32_t>& ids, const std::vector<uint8_t>& moving) {
  check_at_most(dir, name, dense, double(FLT_MAX), N);
  for (size_t i = 0; i < dense.size(); ++i)
    if (dense[i] != 0.0f && !moving[i % N])
      throw_error(join_path(dir, name), ": element ", element(i, N), " is ", dense[i], " for a static Gaussian (static Gaussians carry no motion)");
  const size_t T = N ? dense.size() / N : 0, M = ids.size();
  std::vector<float> out(T * M);
  for (size_t f = 0; f < T; ++f)
    for (size_t j = 0; j < M; ++j) out[f * M + j] = dense[f * N + ids[j]];
  return out;
}

}  // namespace

ObservationFolder read_observation(const std::string& dir) {
  ObservationFolder o;
  o.dir = dir;
  const std::string summary_path = join_path(dir, "summary.json");
  if (!std::filesystem::exists(summary_path)) throw_error(dir, ": no summary.json (not a folder fillgs observe wrote)");
  const nlohmann::json j = read_json_file(summary_path);
  size_t M = 0;
  std::string layout;
  try {
    if (j.value("command", std::string()) != "observe") throw_error(summary_path, ": not written by fillgs observe");
    o.gaussians = j.at("gaussians").get<size_t>();
    M = j.at("dynamic").get<size_t>();
    o.max_views = j.at("max_views_per_frame").get<size_t>();
    const std::string dtype = j.at("count_dtype").get<std::string>();
    if (dtype != "uint8" && dtype != "uint16") throw_error(summary_path, ": count_dtype '", dtype, "', expected uint8 or uint16");
    o.narrow = dtype == "uint8";
    layout = j.contains("tables") ? j.at("tables").get<std::string>() : j.value("motion_tables", std::string("dense"));
  } catch (const nlohmann::json::exception& e) {
    throw_error(summary_path, ": malformed (", e.what(), ")");
  }
  if (M > o.gaussians) throw_error(summary_path, ": ", M, " dynamic Gaussians of ", o.gaussians);
  if (o.max_views > 65535) throw_error(summary_path, ": max_views_per_frame ", o.max_views, " does not fit the 16-bit counts");
  o.layout = parse_name<TableLayout>(layout);
  const size_t N = o.gaussians;
  const std::string cd = count_descr(o.narrow);

  o.times = read_table<double>(dir, "times.npy", "<f8", {rows_of(dir, "times.npy")});
  const size_t T = o.times.size();
  for (size_t f = 0; f < T; ++f) {
    if (!(o.times[f] >= 0.0 && o.times[f] <= 1.0))
      throw_error(join_path(dir, "times.npy"), ": element ", f, " is ", o.times[f], ", not a time in [0, 1]");
    if (f && !(o.times[f] > o.times[f - 1]))
      throw_error(join_path(dir, "times.npy"), ": element ", f, " (", o.times[f], ") does not follow ", o.times[f - 1], ": times increase");
  }
  o.dynamic_ids = read_table<uint32_t>(dir, "dynamic_ids.npy", "<u4", {M});
  std::vector<uint8_t> moving(N, 0);
  for (size_t j = 0; j < M; ++j) {
    const uint32_t g = o.dynamic_ids[j];
    if (g >= N) throw_error(join_path(dir, "dynamic_ids.npy"), ": element ", j, " is ", g, ", outside [0, ", N - 1, "]");
    if (j && g <= o.dynamic_ids[j - 1])
      throw_error(join_path(dir, "dynamic_ids.npy"), ": element ", j, " (", g, ") does not follow ", o.dynamic_ids[j - 1], ": dynamic ids increase");
    moving[g] = 1;
  }
  const double views = double(o.max_views);
  if (o.layout == TableLayout::Compact) {
    o.static_rows = rows_of(dir, "count_static.npy");
    o.count_static = read_table<uint16_t>(dir, "count_static.npy", cd, {o.static_rows, N});
    check_at_most(dir, "count_static.npy", o.count_static, views, N);
    for (size_t r = 0; r < o.static_rows; ++r)
      for (uint32_t g : o.dynamic_ids)
        if (o.count_static[r * N + g])
          throw_error(join_path(dir, "count_static.npy"), ": element ", element(r * N + g, N), " is ", o.count_static[r * N + g],
                      " for a moving Gaussian (its counts are in count_dynamic.npy)");
    o.count_rows = read_table<uint32_t>(dir, "count_rows.npy", "<u4", {T});
    check_at_most(dir, "count_rows.npy", o.count_rows, double(o.static_rows) - 1, 0);
    o.count_dynamic = read_table<uint16_t>(dir, "count_dynamic.npy", cd, {T, M});
    check_at_most(dir, "count_dynamic.npy", o.count_dynamic, views, M);
    o.change_offsets = read_table<int64_t>(dir, "count_change_offsets.npy", "<i8", {T + 1});
    const size_t E = rows_of(dir, "count_change_ids.npy");
    o.change_ids = read_table<uint32_t>(dir, "count_change_ids.npy", "<u4", {E});
    o.change_values = read_table<uint16_t>(dir, "count_change_values.npy", cd, {E});
    check_at_most(dir, "count_change_values.npy", o.change_values, views, 0);
    const std::string offsets = join_path(dir, "count_change_offsets.npy");
    if (o.change_offsets[0] != 0) throw_error(offsets, ": element 0 is ", o.change_offsets[0], ", expected 0");
    for (size_t f = 0; f < T; ++f) {
      const int64_t lo = o.change_offsets[f], hi = o.change_offsets[f + 1];
      if (hi < lo || uint64_t(hi) > E)
        throw_error(offsets, ": element ", f + 1, " is ", hi, ", expected from ", lo, " to the ", E, " changes");
      for (int64_t e = lo; e < hi; ++e) {
        const uint32_t g = o.change_ids[size_t(e)];
        if (g >= N || moving[g] || (e > lo && g <= o.change_ids[size_t(e) - 1]))
          throw_error(join_path(dir, "count_change_ids.npy"), ": element ", e, " is ", g, ", expected increasing ids of static Gaussians below ", N,
                      " within frame ", f);
      }
    }
    if (uint64_t(o.change_offsets[T]) != E) throw_error(offsets, ": element ", T, " is ", o.change_offsets[T], ", expected the ", E, " changes");
  } else {
    o.counts = read_table<uint16_t>(dir, "count.npy", cd, {T, N});
    check_at_most(dir, "count.npy", o.counts, views, N);
  }
  if (o.layout == TableLayout::Dense) {
    o.dynamic_speed = moving_columns(dir, "speed.npy", read_table<float>(dir, "speed.npy", "<f4", {T, N}), N, o.dynamic_ids, moving);
    o.dynamic_deficiency =
        moving_columns(dir, "deficiency.npy", read_table<float>(dir, "deficiency.npy", "<f4", {T, N}), N, o.dynamic_ids, moving);
  } else {
    o.dynamic_speed = read_table<float>(dir, "speed_dynamic.npy", "<f4", {T, M});
    check_at_most(dir, "speed_dynamic.npy", o.dynamic_speed, double(FLT_MAX), M);
    o.dynamic_deficiency = read_table<float>(dir, "deficiency_dynamic.npy", "<f4", {T, M});
    check_at_most(dir, "deficiency_dynamic.npy", o.dynamic_deficiency, double(FLT_MAX), M);
  }
  return o;
}

void ObservationFolder::count_row(size_t f, uint16_t* out) const {
  FILLGS_CHECK(f < frames());
  const size_t N = gaussians, M = dynamic_ids.size();
  if (N == 0) return;
  if (layout != TableLayout::Compact) {
    std::memcpy(out, counts.data() + f * N, N * sizeof(uint16_t));
    return;
  }
  std::memcpy(out, count_static.data() + size_t(count_rows[f]) * N, N * sizeof(uint16_t));
  for (size_t j = 0; j < M; ++j) out[dynamic_ids[j]] = count_dynamic[f * M + j];
  for (int64_t e = change_offsets[f]; e < change_offsets[f + 1]; ++e) out[change_ids[size_t(e)]] = change_values[size_t(e)];
}

}  // namespace fillgs
