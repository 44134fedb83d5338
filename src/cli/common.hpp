#pragma once
// What every command of the front end shares: option parsing, the scene and camera
// options, time grids, timing.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "fillgs/camera.hpp"
#include "fillgs/error.hpp"
#include "fillgs/limits.hpp"
#include "fillgs/scene_io.hpp"
#include "fillgs/timing.hpp"
#include "fillgs/train.hpp"
#include "fillgs/visibility.hpp"

namespace fillgs::cli {

using fillgs::Clock;
using fillgs::seconds_since;

/// `--key value` / `--key=value` options and bare flags, checked against what a command knows.
class Args {
 public:
  Args(const std::string& command, const std::vector<std::string>& args, size_t first, const std::set<std::string>& options,
       const std::set<std::string>& flags)
      : command_(command) {
    for (size_t i = first; i < args.size(); ++i) {
      const std::string& a = args[i];
      if (a.rfind("--", 0) != 0) {
        positional.push_back(a);
        continue;
      }
      std::string key = a.substr(2), value;
      const size_t eq = key.find('=');
      const bool inline_value = eq != std::string::npos;
      if (inline_value) {
        value = key.substr(eq + 1);
        key = key.substr(0, eq);
      }
      if (flags.count(key)) {
        flags_.insert(key);
        continue;
      }
      if (!options.count(key)) throw_error("fillgs ", command, ": unknown option --", key, " (see 'fillgs help')");
      if (!inline_value) {
        if (i + 1 >= args.size()) throw_error("fillgs ", command, ": option --", key, " needs a value");
        value = args[++i];
      }
      values_[key] = value;
    }
  }
  bool flag(const std::string& k) const { return flags_.count(k) > 0; }
  bool has(const std::string& k) const { return values_.count(k) > 0; }
  std::string get(const std::string& k, const std::string& def = "") const {
    auto it = values_.find(k);
    return it == values_.end() ? def : it->second;
  }
  std::string require(const std::string& k) const {
    if (!has(k)) throw_error("fillgs ", command_, ": missing --", k);
    return get(k);
  }
  double number(const std::string& k, double def) const {
    if (!has(k)) return def;
    const std::string v = get(k);
    double x = 0;
    if (!parse_number(v, &x)) throw_error("fillgs ", command_, ": --", k, " expects a number, got '", v, "'");
    return x;
  }
  int integer(const std::string& k, int def) const {
    const double x = number(k, def);
    if (x != std::floor(x) || std::fabs(x) > 1e9) throw_error("fillgs ", command_, ": --", k, " expects an integer");
    return int(x);
  }
  /// --threads: 0 (all cores) or a positive count.
  int threads() const {
    const int n = integer("threads", 0);
    if (n < 0) throw_error("fillgs ", command_, ": --threads must be 0 (all cores) or positive, got ", n);
    return n;
  }
  /// A comma-separated list of numbers ("r,g,b"), each checked.
  std::vector<double> numbers(const std::string& k, size_t count) const {
    const std::string v = get(k);
    std::vector<double> out;
    std::stringstream ss(v);
    std::string part;
    double x = 0;
    while (std::getline(ss, part, ',') && parse_number(part, &x)) out.push_back(x);
    if (out.size() != count || !ss.eof() || (!v.empty() && v.back() == ','))
      throw_error("fillgs ", command_, ": --", k, " expects ", count, " comma-separated numbers, got '", v, "'");
    return out;
  }
  const std::string& command() const { return command_; }
  std::vector<std::string> positional;

 private:
  std::string command_;
  std::map<std::string, std::string> values_;
  std::set<std::string> flags_;
};

inline const std::set<std::string> kSceneOptions = {"scene-format", "duration", "stg-duration", "stg-color", "static-threshold"};
inline const std::set<std::string> kCameraOptions = {"camera-format", "width", "height", "llff-downscale"};

inline std::set<std::string> merge(std::set<std::string> a, const std::set<std::string>& b) {
  a.insert(b.begin(), b.end());
  return a;
}

inline SceneReadOptions scene_options(const Args& a) {
  SceneReadOptions o;
  o.format = parse_scene_format(a.get("scene-format", "auto"));
  o.ex4dgs_duration = a.integer("duration", 0);
  o.stg_duration = a.integer("stg-duration", 50);
  o.stg_color_activation = a.get("stg-color", "auto");
  o.partition.static_speed_threshold = float(a.number("static-threshold", o.partition.static_speed_threshold));
  return o;
}

inline CameraReadOptions camera_options(const Args& a) {
  CameraReadOptions o;
  o.format = parse_camera_format(a.get("camera-format", "auto"));
  o.width = a.integer("width", 0);
  o.height = a.integer("height", 0);
  o.llff_downscale = a.number("llff-downscale", 1.0);
  return o;
}

inline bool progress_enabled(const Args& a) { return !a.flag("quiet") && ::isatty(2); }

/// The time grid: --times list, or --frames F, or what the scene or the cameras imply.
inline std::vector<double> observe_times(const Args& a, const GaussianCloud& cloud, const std::vector<Camera>& cams, double* frame_step) {
  int frames = a.integer("frames", 0);
  if (a.has("frames") && frames < 2) throw_error("fillgs ", a.command(), ": --frames must be at least 2 (got ", frames, ")");
  if (!frames && cloud.motion == MotionModel::Keyframed && cloud.keyframed.first_key_time == 0.0 && cloud.keyframed.key_count >= 2 &&
      std::fabs(cloud.keyframed.key_spacing * (cloud.keyframed.key_count - 1) - 1.0) < 1e-6)
    frames = cloud.keyframed.key_count;  // one key per frame
  if (!frames) {
    std::set<long long> distinct;
    for (const Camera& c : cams)
      if (c.has_time()) distinct.insert(std::llround(c.time * 1e6));
    if (distinct.size() >= 2) frames = int(distinct.size());
  }
  if (a.has("times")) {
    std::vector<double> times;
    std::istringstream in(a.get("times"));
    std::string tok;
    while (std::getline(in, tok, ',')) {
      char* end = nullptr;
      const double t = std::strtod(tok.c_str(), &end);
      if (end == tok.c_str() || *end != '\0' || !(t >= 0.0 && t <= 1.0))
        throw_error("fillgs ", a.command(), ": --times expects comma-separated times in [0, 1], got '", tok, "'");
      times.push_back(t);
    }
    std::sort(times.begin(), times.end());
    times.erase(std::unique(times.begin(), times.end()), times.end());
    if (times.empty()) throw_error("fillgs ", a.command(), ": --times is empty");
    if (!frames) throw_error("fillgs ", a.command(), ": give --frames F with --times (the speed's Δt is one frame, 1/(F-1))");
    *frame_step = 1.0 / (frames - 1);
    return times;
  }
  if (!frames)
    throw_error("fillgs ", a.command(), ": cannot tell the frame count from the scene or the cameras; give --frames F");
  *frame_step = 1.0 / (frames - 1);
  return frame_times(frames);
}

inline std::vector<std::string> split_commas(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

/// --frames first:last:step, --downscale k and --monocular-cycle a,b,… for the commands that
/// read images.
inline const std::set<std::string> kDatasetOptions = {"frames", "downscale", "monocular-cycle", "image-memory"};
inline DatasetOptions dataset_options(const Args& a, const std::string& cameras_key) {
  DatasetOptions o;
  o.cameras = split_commas(a.get(cameras_key));
  o.frames = FrameRange::parse(a.get("frames"));
  o.downscale = a.integer("downscale", 1);
  o.monocular_cycle = split_commas(a.get("monocular-cycle"));
  if (o.downscale < 1) throw_error("fillgs ", a.command(), ": --downscale must be at least 1");
  if (a.has("image-memory")) {
    const double gb = a.number("image-memory", 0.0);
    if (!(gb >= 0 && gb < 1e6)) throw_error("fillgs ", a.command(), ": --image-memory must be a number of GB, at least 0 (got ", a.get("image-memory"), ")");
    o.image_memory = int64_t(gb * double(int64_t(1) << 30));
  }
  return o;
}

}  // namespace fillgs::cli
