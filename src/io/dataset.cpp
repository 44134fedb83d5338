// Multi-view video for training and evaluation (dataset.hpp).
#include "fillgs/io/dataset.hpp"
#include "fillgs/io/camera_io.hpp"

#include <nlohmann/json.hpp>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <mutex>
#include <numeric>
#include <sstream>
#include <utility>

#include "fillgs/base/error.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/base/json_file.hpp"
#include "fillgs/io/video.hpp"

namespace fs = std::filesystem;

namespace fillgs {

namespace {

std::string rig_of(const std::string& name) {
  const size_t slash = name.find('/');
  return slash == std::string::npos ? name : name.substr(0, slash);
}

/// The first `channels` channels of `im` as 8-bit, averaged over k×k blocks.
std::vector<uint8_t> block_average(const Image& im, int channels, int k) {
  const int order[3] = {0, 1, 2};
  return block_average_u8(im.pixels.data(), im.width, im.height, im.channels, channels, order, k, 255.0f);
}

/// The camera of an image downscaled by k (block_average).
void scale_camera(Camera& c, int k) {
  if (k == 1) return;
  c.width /= k, c.height /= k;
  c.fx /= k, c.fy /= k, c.cx /= k, c.cy /= k;
}

/// Technicolor's frames of camera `camNN` in one folder, as its preprocessing names them:
/// `<Scene>_undist_<5-digit frame>_<NN>.png`, sorted by frame ("" if `rig` is not camNN).
std::vector<std::string> technicolor_frames(const std::string& folder, const std::string& rig) {
  std::vector<std::string> files;
  if (rig.size() != 5 || rig.compare(0, 3, "cam") != 0 || !std::isdigit(static_cast<unsigned char>(rig[3])) ||
      !std::isdigit(static_cast<unsigned char>(rig[4])))
    return files;
  const std::string tail = "_" + rig.substr(3) + ".png";
  for (const auto& e : fs::directory_iterator(folder)) {
    const std::string name = e.path().filename().string();
    const size_t u = name.rfind("_undist_");
    // "_undist_" + 5 digits + "_NN.png" closes the name.
    if (!e.is_regular_file() || u == std::string::npos || name.size() != u + 8 + 5 + tail.size() ||
        name.compare(name.size() - tail.size(), tail.size(), tail) != 0)
      continue;
    if (std::all_of(name.begin() + long(u) + 8, name.begin() + long(u) + 13, [](char c) { return std::isdigit(static_cast<unsigned char>(c)); }))
      files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());  // same scene prefix: the 5-digit frame orders them
  return files;
}

std::string first_existing(const std::vector<fs::path>& candidates) {
  for (const fs::path& p : candidates)
    if (fs::is_regular_file(p)) return p.string();
  return "";
}

}  // namespace

// ---------------------------------------------------------------------------------
// Dataset

FrameRange FrameRange::parse(const std::string& text) {
  FrameRange r;
  if (text.empty() || text == ":") return r;
  std::vector<std::string> parts(1);
  for (char c : text) {
    if (c == ':') parts.emplace_back();
    else parts.back() += c;
  }
  auto whole = [&](const std::string& p, int fallback) {
    if (p.empty()) return fallback;
    if (p.find_first_not_of("0123456789") != std::string::npos)
      throw_error("frame range \"", text, "\": '", p, "' is not a frame number (first:last:step, e.g. 0:150:5)");
    if (p.size() > 9)
      throw_error("frame range \"", text, "\": ", p, " is more frames than fillgs reads from a video (at most 999999999)");
    return int(std::strtol(p.c_str(), nullptr, 10));
  };
  if (parts.size() > 3) throw_error("frame range \"", text, "\": expected first:last:step");
  r.first = whole(parts[0], 0);
  r.last = parts.size() > 1 ? whole(parts[1], -1) : -1;
  r.step = parts.size() > 2 ? whole(parts[2], 1) : 1;
  if (r.step < 1) throw_error("frame range \"", text, "\": the step must be at least 1");
  if (r.last >= 0 && r.last <= r.first) throw_error("frame range \"", text, "\": last must come after first");
  return r;
}

Dataset Dataset::load(const std::string& images_dir, const std::string& cameras_path, const DatasetOptions& opt, Progress& progress) {
  if (!fs::is_directory(images_dir)) throw_error(images_dir, ": images folder not found");
  if (opt.downscale < 1 || opt.downscale > 64) throw_error("downscale ", opt.downscale, ": must be 1 to 64");
  std::vector<Camera> cams = read_cameras(cameras_path);
  if (cams.empty()) throw_error(cameras_path, ": no cameras");
  // Neural 3D Video as distributed: poses_bounds.npy's rows are the folder's videos, sorted.
  const std::vector<std::string> videos = videos_in(images_dir);
  if (!videos.empty() && fs::path(cameras_path).extension() == ".npy") {
    if (videos.size() != cams.size())
      throw_error(cameras_path, ": ", cams.size(), " rows, but ", images_dir, " holds ", videos.size(), " videos (one row per video, sorted by name)");
    for (size_t i = 0; i < cams.size(); ++i) cams[i].name = fs::path(videos[i]).stem().string();
  }
  Dataset d;
  const bool timed = std::all_of(cams.begin(), cams.end(), [](const Camera& c) { return c.has_time(); });
  if (!opt.camera_times.empty() && opt.cameras.empty())
    throw_error(cameras_path, ": single camera-times are added to the cameras trained on at every frame, and none were named");
  auto wanted = [&](const std::string& rig) {
    return opt.cameras.empty() || std::find(opt.cameras.begin(), opt.cameras.end(), rig) != opt.cameras.end() ||
           std::any_of(opt.camera_times.begin(), opt.camera_times.end(), [&](const auto& ct) { return ct.first == rig; });
  };
  const fs::path base = fs::path(cameras_path).parent_path();
  std::vector<std::string> mask_rel;  // per view: its image's path under the images folder
  if (timed) {
    std::vector<double> times;
    for (const Camera& c : cams) times.push_back(c.time);
    std::sort(times.begin(), times.end());
    times.erase(std::unique(times.begin(), times.end()), times.end());
    d.frames_ = int(times.size());
    for (const Camera& c : cams) {
      // "images/cam00/0000" → rig "cam00"
      std::string rel = c.image_path.empty() ? c.name + ".png" : c.image_path;
      if (rel.rfind("./", 0) == 0) rel = rel.substr(2);
      std::string stripped = rel.rfind("images/", 0) == 0 ? rel.substr(7) : rel;
      const std::string rig = rig_of(stripped);
      if (!wanted(rig)) continue;
      TrainView v;
      v.camera = c;
      v.rig = rig;
      v.frame = v.source_frame = int(std::lower_bound(times.begin(), times.end(), c.time) - times.begin());
      // Dynamic 3D Gaussians keeps its images in ims/ beside the meta file.
      std::vector<fs::path> cand = {fs::path(images_dir) / stripped, fs::path(images_dir) / rel, base / rel, base / "ims" / rel};
      if (fs::path(rel).extension().empty())
        for (auto p : std::vector<fs::path>(cand)) cand.push_back(p.string() + ".png");
      v.image_path = first_existing(cand);
      if (v.image_path.empty()) throw_error(cameras_path, ": camera '", c.name, "' has no image (looked for ", cand[0].string(), ")");
      d.views_.push_back(v);
      mask_rel.push_back(stripped);
    }
  } else {
    std::map<std::string, const Camera*> rigs;
    for (const Camera& c : cams) rigs[rig_of(c.name)] = &c;
    int frames = -1;
    for (const auto& [rig, cam] : rigs) {
      if (!wanted(rig)) continue;
      const fs::path folder = fs::path(images_dir) / rig, video = fs::path(images_dir) / (rig + ".mp4");
      if (!fs::is_directory(folder) && fs::is_regular_file(video)) {
        // A video per camera: its frames, decoded when the images are loaded below.
        const VideoInfo info = probe_video(video.string());
        if (info.width != cam->width || info.height != cam->height)
          throw_error(video.string(), ": frames are ", info.width, "x", info.height, " but camera '", rig, "' is ", cam->width, "x", cam->height,
                      " (scale with --downscale, not the camera file)");
        if (frames >= 0 && info.frames != frames) throw_error(video.string(), ": ", info.frames, " frames, but other cameras have ", frames);
        frames = info.frames;
        for (int f = 0; f < frames; ++f) {
          TrainView v;
          v.camera = *cam;
          v.camera.time = FrameGrid(frames).time(f);
          char name[24];
          std::snprintf(name, sizeof name, "%06d", f);
          v.camera.name = rig + "/" + name;
          v.rig = rig;
          v.frame = v.source_frame = f;
          v.image_path = video.string();
          d.views_.push_back(v);
          mask_rel.push_back(rig + "/" + name + ".png");
        }
        continue;
      }
      std::vector<std::string> files;
      if (fs::is_directory(folder))
        for (const auto& e : fs::directory_iterator(folder)) {
          const std::string ext = e.path().extension().string();
          if (e.is_regular_file() && (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".exr")) files.push_back(e.path().string());
        }
      else
        files = technicolor_frames(images_dir, rig);
      // One image per camera beside the others (a single frame: images/cam00.png).
      for (const char* ext : {".png", ".jpg", ".jpeg"})
        if (files.empty() && fs::is_regular_file(fs::path(images_dir) / (rig + ext))) files.push_back((fs::path(images_dir) / (rig + ext)).string());
      if (files.empty())
        throw_error(cameras_path, ": camera '", rig, "' has no images in ", folder.string(), ", no ", video.string(),
                    " and no Technicolor frames <Scene>_undist_<frame>_", rig.size() > 2 ? rig.substr(rig.size() - 2) : rig, ".png in ", images_dir);
      std::sort(files.begin(), files.end());
      if (frames >= 0 && int(files.size()) != frames)
        throw_error(folder.string(), ": ", files.size(), " frames, but other cameras have ", frames);
      frames = int(files.size());
      for (int f = 0; f < frames; ++f) {
        TrainView v;
        v.camera = *cam;
        v.camera.time = FrameGrid(frames).time(f);
        v.camera.name = rig + "/" + fs::path(files[size_t(f)]).stem().string();
        v.rig = rig;
        v.frame = v.source_frame = f;
        v.image_path = files[size_t(f)];
        d.views_.push_back(v);
        mask_rel.push_back(rig + "/" + fs::path(files[size_t(f)]).filename().string());
      }
    }
    d.frames_ = std::max(frames, 1);
  }
  for (const std::pair<std::string, int>& ct : opt.camera_times)
    if (std::none_of(d.views_.begin(), d.views_.end(), [&](const TrainView& v) { return v.rig == ct.first; }))
      throw_error(cameras_path, ": no camera named '", ct.first, "' (a single camera-time asks for it at frame ", ct.second, ")");
  for (const std::string& want : opt.cameras) {
    bool found = false;
    for (const TrainView& v : d.views_) found = found || v.rig == want;
    if (!found) throw_error(cameras_path, ": no camera named '", want, "'");
  }
  if (d.views_.empty()) throw_error(cameras_path, ": no training views");
  d.keep_frames(opt.frames, &mask_rel, cameras_path);
  if (!opt.camera_times.empty()) d.keep_camera_times(opt, &mask_rel, cameras_path);
  if (!opt.monocular_cycle.empty()) d.keep_cycle(opt.monocular_cycle, &mask_rel, cameras_path);
  for (const TrainView& v : d.views_)
    if (std::find(d.rigs_.begin(), d.rigs_.end(), v.rig) == d.rigs_.end()) d.rigs_.push_back(v.rig);
  if (!opt.held_out.empty()) {
    const std::vector<Camera> held = read_cameras(opt.held_out);
    for (const TrainView& v : d.views_)
      for (const Camera& h : held) {
        // The angle of the relative rotation R_v R_h^T: acos((trace - 1) / 2).
        const double cos_angle = std::clamp(((v.camera.R * h.R.transpose()).trace() - 1.0) / 2.0, -1.0, 1.0);
        const double distance = (v.camera.centre() - h.centre()).norm(), degrees = std::acos(cos_angle) * 180.0 / kPi;
        if (distance <= opt.held_out_distance && degrees <= opt.held_out_degrees)
          throw_error(cameras_path, ": camera '", v.rig, "' stands where held-out camera '", h.name, "' of ", opt.held_out, " stands (",
                      distance, " units and ", degrees, " degrees apart; within --held-out-distance ", opt.held_out_distance,
                      " and --held-out-angle ", opt.held_out_degrees, "): a held-out camera is never trained on, pooled or chosen");
      }
  }
  // Foreground masks where a seg/ folder stands beside the camera file.
  const fs::path seg = base / "seg";
  std::error_code seg_ec;
  if (fs::is_symlink(seg, seg_ec) && !fs::exists(seg, seg_ec))
    throw_error(seg.string(), ": a link to '", fs::read_symlink(seg, seg_ec).string(),
                "', which does not exist (the foreground masks beside the camera file; a relative link is read from its own folder)");
  if (fs::exists(seg, seg_ec) && !fs::is_directory(seg, seg_ec))
    throw_error(seg.string(), ": not a folder", fs::is_symlink(seg, seg_ec) ? " (a link to '" + fs::read_symlink(seg, seg_ec).string() + "')" : std::string(),
                "; the foreground masks beside the camera file are a folder seg/ of PNGs (remove or rename it to train without masks)");
  const bool masked = fs::is_directory(seg);
  // Load every image (and mask) once, 8-bit, checking sizes; downscaled by k; held in
  // memory or, past the budget, in the image cache file.
  const int k = opt.downscale;
  std::vector<size_t> sizes;
  for (const TrainView& v : d.views_) {
    if (v.camera.width / k < 1 || v.camera.height / k < 1)
      throw_error("downscale ", k, " leaves no pixel of camera '", v.camera.name, "' (", v.camera.width, "x", v.camera.height, ")");
    sizes.push_back(size_t(v.camera.width / k) * size_t(v.camera.height / k) * 3);
  }
  d.pixels_.reset(sizes, opt.image_memory < 0 ? default_image_budget() : size_t(opt.image_memory), opt.spill_dir);
  if (masked) d.masks_.resize(d.views_.size());
  std::mutex progress_mutex;  // the reporter is not thread-safe
  const auto loaded = [&] {
    std::lock_guard<std::mutex> lock(progress_mutex);
    progress.advance();
  };
  progress.start("images", d.views_.size());
  // Videos: decoded once each, in order, keeping the frames of their views.
  std::map<std::string, std::vector<size_t>> by_video;
  for (size_t i = 0; i < d.views_.size(); ++i)
    if (fs::path(d.views_[i].image_path).extension() == ".mp4") by_video[d.views_[i].image_path].push_back(i);
  std::vector<std::pair<std::string, std::vector<size_t>>> video_list(by_video.begin(), by_video.end());
  tbb::parallel_for(size_t(0), video_list.size(), [&](size_t j) {
    const std::string& path = video_list[j].first;
    const std::vector<size_t>& vs = video_list[j].second;  // named, not a structured binding: lambdas capture it
    std::vector<int> frames;
    for (size_t i : vs) frames.push_back(d.views_[i].source_frame);
    const Camera& c = d.views_[vs[0]].camera;
    decode_video_frames(path, frames, k, c.width, c.height, [&](size_t n, std::vector<uint8_t>&& px) {
      d.pixels_.put(vs[n], std::move(px));
      loaded();
    });
  });
  tbb::parallel_for(size_t(0), d.views_.size(), [&](size_t i) {
    TrainView& v = d.views_[i];
    // Video frames were decoded above (their size checked there); images are read here.
    if (fs::path(v.image_path).extension() != ".mp4") {
      const Image im = read_image(v.image_path);
      if (im.width != v.camera.width || im.height != v.camera.height)
        throw_error(v.image_path, ": image is ", im.width, "x", im.height, " but camera '", v.camera.name, "' is ",
                    v.camera.width, "x", v.camera.height);
      if (im.channels < 3) throw_error(v.image_path, ": ", im.channels, " channels, RGB needed");
      d.pixels_.put(i, block_average(im, 3, k));
      loaded();
    }
    if (masked) {
      const fs::path mp = (seg / mask_rel[i]).replace_extension(".png");
      if (!fs::is_regular_file(mp)) throw_error(mp.string(), ": no foreground mask for ", v.image_path, " (", seg.string(), " holds masks)");
      const Image m = read_image(mp.string());
      if (m.width != v.camera.width || m.height != v.camera.height)
        throw_error(mp.string(), ": mask is ", m.width, "x", m.height, " but its image is ", v.camera.width, "x", v.camera.height);
      std::vector<uint8_t> fg = block_average(m, 1, k);
      for (uint8_t& x : fg) x = x > 127 ? 1 : 0;
      d.masks_[i] = std::move(fg);
    }
    scale_camera(v.camera, k);
  });
  progress.finish();
  return d;
}

void Dataset::keep_frames(const FrameRange& range, std::vector<std::string>* per_view, const std::string& source) {
  if (range.all()) return;
  const int F = frames_, last = range.last < 0 ? F : std::min(range.last, F);
  std::vector<int> renumber(size_t(F), -1);
  int n = 0;
  for (int f = range.first; f < last; f += range.step) renumber[size_t(f)] = n++;
  if (n == 0) throw_error(source, ": frames ", range.first, ":", range.last, ":", range.step, " selects none of its ", F, " frames");
  std::vector<TrainView> kept;
  std::vector<std::string> kept_side;
  for (size_t i = 0; i < views_.size(); ++i) {
    TrainView v = views_[i];
    const int j = renumber[size_t(FrameGrid(F).clamp(v.frame))];
    if (j < 0) continue;
    v.frame = j;
    v.camera.time = n > 1 ? double(j) / double(n - 1) : 0.0;
    kept.push_back(std::move(v));
    if (per_view) kept_side.push_back((*per_view)[i]);
  }
  views_ = std::move(kept);
  if (per_view) *per_view = std::move(kept_side);
  source_frames_ = F;
  frames_ = n;
}

void Dataset::keep_camera_times(const DatasetOptions& opt, std::vector<std::string>* per_view, const std::string& source) {
  std::set<std::pair<std::string, int>> single;
  for (const auto& [rig, frame] : opt.camera_times) {
    if (frame < 0 || frame >= frames_)
      throw_error(source, ": camera-time ", rig, " at frame ", frame, ": the video has frames 0 to ", frames_ - 1, " (numbered after the frame range)");
    single.insert({rig, frame});
  }
  std::vector<TrainView> kept;
  std::vector<std::string> kept_side;
  for (size_t i = 0; i < views_.size(); ++i) {
    const TrainView& v = views_[i];
    const bool every_frame = std::find(opt.cameras.begin(), opt.cameras.end(), v.rig) != opt.cameras.end();
    if (!every_frame && !single.erase({v.rig, v.frame})) continue;
    kept.push_back(v);
    if (per_view) kept_side.push_back((*per_view)[i]);
  }
  for (const auto& [rig, frame] : single)
    if (std::find(opt.cameras.begin(), opt.cameras.end(), rig) == opt.cameras.end())
      throw_error(source, ": camera '", rig, "' has no view at frame ", frame);
  views_ = std::move(kept);
  if (per_view) *per_view = std::move(kept_side);
}

void Dataset::keep_cycle(const std::vector<std::string>& cycle, std::vector<std::string>* per_view, const std::string& source) {
  for (const std::string& c : cycle)
    if (std::none_of(views_.begin(), views_.end(), [&](const TrainView& v) { return v.rig == c; }))
      throw_error(source, ": the monocular cycle names camera '", c, "', which the dataset does not have");
  std::vector<TrainView> kept;
  std::vector<std::string> kept_side;
  for (size_t i = 0; i < views_.size(); ++i) {
    if (views_[i].rig != cycle[size_t(views_[i].frame) % cycle.size()]) continue;
    kept.push_back(views_[i]);
    if (per_view) kept_side.push_back((*per_view)[i]);
  }
  views_ = std::move(kept);
  if (per_view) *per_view = std::move(kept_side);
}

std::vector<float> Dataset::image(size_t view) const {
  std::vector<uint8_t> scratch;
  const std::vector<uint8_t>& px = pixels_.get(view, scratch);
  std::vector<float> out(px.size());
  for (size_t i = 0; i < px.size(); ++i) out[i] = float(px[i]) / 255.0f;
  return out;
}

std::vector<uint8_t> Dataset::take_image8(size_t view) { return pixels_.take(view); }

std::pair<Vec3f, float> Dataset::camera_extent() const {
  Vec3d c = Vec3d::Zero();
  for (const TrainView& v : views_) c += v.camera.centre();
  c /= double(views_.size());
  double r = 0;
  for (const TrainView& v : views_) r = std::max(r, (v.camera.centre() - c).norm());
  return {c.cast<float>(), float(std::max(r, 1e-6) * 1.1)};
}

}  // namespace fillgs
