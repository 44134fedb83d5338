#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "fillgs/model/frame_grid.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/model/camera.hpp"
#include "fillgs/io/camera_json.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/base/json_file.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/io/npy.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace fillgs {

namespace {
constexpr double kMinFocal = 1e-3, kMaxFocal = 1e9, kMaxCoordinate = 1e7;
}  // namespace

void check_camera(const std::string& source, const std::string& element, const Camera& c) {
  const bool ok = std::isfinite(c.fx) && std::isfinite(c.fy) && std::isfinite(c.cx) && std::isfinite(c.cy) &&
                  c.R.allFinite() && c.t.allFinite() && c.fx > 0 && c.fy > 0 && c.width > 0 && c.height > 0;
  if (!ok) throw_error(source, ": ", element, " has a non-finite or non-positive value (f ", c.fx, ", ", c.fy,
                       ", size ", c.width, "x", c.height, ")");
  // What the renderer and the tracer (single precision) can represent: a focal length of at
  // least a thousandth of a pixel (a field of view under 180 degrees) and at most 1e9 pixels,
  // a principal point and a camera position within 1e7 of the origin.
  if (!(c.fx >= kMinFocal && c.fy >= kMinFocal && c.fx <= kMaxFocal && c.fy <= kMaxFocal))
    throw_error(source, ": ", element, " has focal length (", c.fx, ", ", c.fy, ") pixels, outside [", kMinFocal, ", ", kMaxFocal, "]");
  if (!(std::abs(c.cx) <= kMaxCoordinate && std::abs(c.cy) <= kMaxCoordinate))
    throw_error(source, ": ", element, " has principal point (", c.cx, ", ", c.cy, "), beyond ", kMaxCoordinate, " pixels");
  if (!(c.t.cwiseAbs().maxCoeff() <= kMaxCoordinate && c.centre().cwiseAbs().maxCoeff() <= kMaxCoordinate))
    throw_error(source, ": ", element, " stands at (", c.centre().x(), ", ", c.centre().y(), ", ", c.centre().z(), "), beyond ", kMaxCoordinate,
                " world units from the origin, where single precision loses the scene");
  image_side(c.width, source, element, "width");
  image_side(c.height, source, element, "height");
  check_allocation(size_t(c.width) * size_t(c.height) * 32, source, element + " (" + std::to_string(c.width) + "x" +
                                                                        std::to_string(c.height) + ") render buffers");
  const double err = (c.R * c.R.transpose() - Mat3d::Identity()).cwiseAbs().maxCoeff();
  if (!(err < 1e-3) || c.R.determinant() < 0)
    throw_error(source, ": ", element, " has a rotation that is not one (|R R^T - I| = ", err, ", det ", c.R.determinant(),
                "): a scaled, reflected or degenerate pose");
  if (c.has_time() && !std::isfinite(c.time)) throw_error(source, ": ", element, " has a non-finite time");
  if (c.has_time() && (c.time < 0 || c.time > 1))
    throw_error(source, ": ", element, " has time ", c.time, " outside [0, 1] (fillgs times are normalised)");
}

namespace {

std::string strip_extension_and_dot(std::string p) {
  if (p.rfind("./", 0) == 0) p = p.substr(2);
  const fs::path fp(p);
  if (fp.has_extension()) p = (fp.parent_path() / fp.stem()).string();
  return p;
}

/// A rotation from a stored quaternion; a zero or non-finite one is refused.
Mat3d quat_wxyz_to_matrix(const std::string& source, const std::string& element, double w, double x, double y, double z) {
  Vec4d q(w, x, y, z);
  if (!q.allFinite() || !(q.norm() > 1e-9))
    throw_error(source, ": ", element, " has a zero or non-finite quaternion (", w, ", ", x, ", ", y, ", ", z, ")");
  q.normalize();
  return quat_to_matrix<double>(q);
}

// ---------------------------------------------------------------- COLMAP

struct ColmapIntrinsics {
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
};

const char* colmap_model_name(int id) {
  static const char* names[] = {"SIMPLE_PINHOLE", "PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV", "OPENCV_FISHEYE",
                                "FULL_OPENCV", "FOV", "SIMPLE_RADIAL_FISHEYE", "RADIAL_FISHEYE", "THIN_PRISM_FISHEYE",
                                "RAD_TAN_THIN_PRISM_FISHEYE", "SIMPLE_DIVISION", "DIVISION", "SIMPLE_FISHEYE",
                                "FISHEYE", "EUCM", "EQUIRECTANGULAR"};
  return (id >= 0 && id < 18) ? names[id] : "unknown";
}

ColmapIntrinsics colmap_pinhole(const std::string& source, long id, const std::string& model, const std::vector<double>& p,
                                int w, int h) {
  ColmapIntrinsics k;
  k.width = w;
  k.height = h;
  if (model == "SIMPLE_PINHOLE") {
    if (p.size() < 3) throw_error(source, ": camera ", id, " SIMPLE_PINHOLE needs 3 parameters, has ", p.size());
    k.fx = k.fy = p[0];
    k.cx = p[1];
    k.cy = p[2];
  } else if (model == "PINHOLE") {
    if (p.size() < 4) throw_error(source, ": camera ", id, " PINHOLE needs 4 parameters, has ", p.size());
    k.fx = p[0];
    k.fy = p[1];
    k.cx = p[2];
    k.cy = p[3];
  } else {
    throw_error(source, ": camera ", id, " uses model ", model,
                ", which fillgs does not undistort (supported: PINHOLE, SIMPLE_PINHOLE; run colmap image_undistorter)");
  }
  return k;
}

struct ColmapImage {
  long id;
  double q[4], t[3];
  long camera_id;
  std::string name;
};

std::vector<Camera> assemble_colmap(const std::string& source, const std::map<long, ColmapIntrinsics>& intr,
                                    std::vector<ColmapImage> images) {
  std::sort(images.begin(), images.end(), [](const ColmapImage& a, const ColmapImage& b) { return a.name < b.name; });
  std::vector<Camera> cams;
  for (const ColmapImage& im : images) {
    auto it = intr.find(im.camera_id);
    if (it == intr.end()) throw_error(source, ": image ", im.id, " ('", im.name, "') refers to missing camera ", im.camera_id);
    Camera c;
    c.name = strip_extension_and_dot(im.name);
    c.image_path = im.name;
    c.width = it->second.width;
    c.height = it->second.height;
    c.fx = it->second.fx;
    c.fy = it->second.fy;
    c.cx = it->second.cx;
    c.cy = it->second.cy;
    c.R = quat_wxyz_to_matrix(source, "image " + std::to_string(im.id), im.q[0], im.q[1], im.q[2], im.q[3]);
    c.t = Vec3d(im.t[0], im.t[1], im.t[2]);
    check_camera(source, "image " + std::to_string(im.id), c);
    cams.push_back(c);
  }
  return cams;
}

std::vector<Camera> read_colmap_text(const std::string& dir) {
  const std::string cam_path = join_path(dir, "cameras.txt"), img_path = join_path(dir, "images.txt");
  std::map<long, ColmapIntrinsics> intr;
  {
    std::istringstream in(read_file(cam_path));
    std::string line;
    int line_no = 0;
    while (std::getline(in, line)) {
      ++line_no;
      if (line.empty() || line[0] == '#' || line.find_first_not_of(" \t\r") == std::string::npos) continue;
      std::istringstream ls(line);
      long id;
      std::string model;
      long w, h;
      if (!(ls >> id >> model >> w >> h)) throw_error(cam_path, ": line ", line_no, ": malformed camera line");
      std::vector<double> p;
      double v;
      while (ls >> v) p.push_back(v);
      const std::string el = "camera " + std::to_string(id);
      intr[id] = colmap_pinhole(cam_path, id, model, p, image_side(double(w), cam_path, el, "width"),
                                image_side(double(h), cam_path, el, "height"));
    }
  }
  std::vector<ColmapImage> images;
  {
    std::istringstream in(read_file(img_path));
    std::string line;
    int line_no = 0;
    bool expect_points = false;
    while (std::getline(in, line)) {
      ++line_no;
      if (!line.empty() && line[0] == '#') continue;
      if (expect_points) {  // the 2D-point line, possibly empty
        expect_points = false;
        continue;
      }
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      std::istringstream ls(line);
      ColmapImage im;
      if (!(ls >> im.id >> im.q[0] >> im.q[1] >> im.q[2] >> im.q[3] >> im.t[0] >> im.t[1] >> im.t[2] >> im.camera_id >> im.name))
        throw_error(img_path, ": line ", line_no, ": malformed image line");
      images.push_back(im);
      expect_points = true;
    }
  }
  return assemble_colmap(img_path, intr, images);
}

class BinaryReader {
 public:
  BinaryReader(std::string path) : path_(std::move(path)), data_(read_file(path_)) {}
  template <typename T>
  T get(const char* what) {
    if (pos_ + sizeof(T) > data_.size()) throw_error(path_, ": truncated while reading ", what, " at byte ", pos_);
    T v;
    std::memcpy(&v, data_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  std::string cstring(const char* what) {
    const size_t e = data_.find('\0', pos_);
    if (e == std::string::npos) throw_error(path_, ": truncated while reading ", what);
    std::string s = data_.substr(pos_, e - pos_);
    pos_ = e + 1;
    return s;
  }
  /// Skips `count` records of `size` bytes; the count is checked against the bytes left
  /// before anything is multiplied.
  void skip_records(uint64_t count, size_t size, const char* what) {
    if (count > (data_.size() - pos_) / size)
      throw_error(path_, ": ", what, " count ", count, " at byte ", pos_, " needs more bytes than the file has (truncated or corrupt)");
    pos_ += size_t(count) * size;
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::string data_;
  size_t pos_ = 0;
};

std::vector<Camera> read_colmap_binary(const std::string& dir) {
  static const int param_counts[] = {3, 4, 4, 5, 8, 8, 12, 5, 4, 5, 12};
  std::map<long, ColmapIntrinsics> intr;
  {
    BinaryReader r(join_path(dir, "cameras.bin"));
    const uint64_t n = r.get<uint64_t>("camera count");
    for (uint64_t i = 0; i < n; ++i) {
      const int32_t id = r.get<int32_t>("camera id");
      const int32_t model = r.get<int32_t>("camera model");
      const uint64_t w = r.get<uint64_t>("width"), h = r.get<uint64_t>("height");
      if (model < 0 || model > 10)
        throw_error(r.path(), ": camera ", id, " uses model id ", model, " (", colmap_model_name(model),
                    "), which fillgs cannot read (binary records carry no length; supported: PINHOLE, SIMPLE_PINHOLE)");
      std::vector<double> p(static_cast<size_t>(param_counts[model]));
      for (double& v : p) v = r.get<double>("camera parameters");
      const std::string el = "camera " + std::to_string(id);
      intr[id] = colmap_pinhole(r.path(), id, colmap_model_name(model), p, image_side(double(w), r.path(), el, "width"),
                                image_side(double(h), r.path(), el, "height"));
    }
  }
  std::vector<ColmapImage> images;
  BinaryReader r(join_path(dir, "images.bin"));
  const uint64_t n = r.get<uint64_t>("image count");
  for (uint64_t i = 0; i < n; ++i) {
    ColmapImage im;
    im.id = r.get<int32_t>("image id");
    for (double& v : im.q) v = r.get<double>("quaternion");
    for (double& v : im.t) v = r.get<double>("translation");
    im.camera_id = r.get<int32_t>("camera id");
    im.name = r.cstring("image name");
    const uint64_t np = r.get<uint64_t>("point count");
    r.skip_records(np, 24, "2D points");
    images.push_back(im);
  }
  return assemble_colmap(r.path(), intr, images);
}

std::vector<Camera> read_colmap(const std::string& path) {
  std::error_code ec;
  std::string dir = fs::is_directory(path, ec) ? path : fs::path(path).parent_path().string();
  for (const char* sub : {"", "sparse/0", "sparse"}) {
    const std::string d = join_path(dir, sub);
    if (fs::exists(join_path(d, "cameras.bin"), ec) && fs::exists(join_path(d, "images.bin"), ec)) return read_colmap_binary(d);
    if (fs::exists(join_path(d, "cameras.txt"), ec) && fs::exists(join_path(d, "images.txt"), ec)) return read_colmap_text(d);
  }
  throw_error(path, ": no COLMAP model (cameras.{bin,txt} and images.{bin,txt}) here or in sparse/0");
}

// ---------------------------------------------------------------- LLFF

std::vector<Camera> read_llff(const std::string& path, const CameraReadOptions& opt) {
  const NpyArray a = read_npy(path);
  if (a.shape.size() != 2 || a.shape[1] != 17)
    throw_error(path, ": LLFF poses_bounds.npy must have shape (N, 17), not (", a.shape.size() ? a.shape[0] : 0, ", ...)");
  const std::vector<double> v = a.to_doubles(path);
  if (!(opt.llff_downscale > 0)) throw_error("LLFF downscale must be positive");
  std::vector<Camera> cams;
  for (size_t i = 0; i < a.shape[0]; ++i) {
    const double* r = &v[i * 17];
    for (int k = 0; k < 17; ++k)
      if (!std::isfinite(r[k])) throw_error(path, ": row ", i, " column ", k, " is not finite");
    auto col = [&](int c) { return Vec3d(r[0 * 5 + c], r[1 * 5 + c], r[2 * 5 + c]); };
    Mat3d c2w;
    c2w.col(0) = col(1);   // right
    c2w.col(1) = col(0);   // down
    c2w.col(2) = -col(2);  // forward = -back
    Camera c;
    char name[32];
    std::snprintf(name, sizeof name, "cam%02zu", i);
    c.name = name;
    const Vec3d hwf = col(4);
    c.height = int(std::lround(hwf[0] / opt.llff_downscale));
    c.width = int(std::lround(hwf[1] / opt.llff_downscale));
    c.fx = c.fy = hwf[2] / opt.llff_downscale;
    c.cx = c.width / 2.0;
    c.cy = c.height / 2.0;
    c.R = c2w.transpose();
    c.t = -c.R * col(3);
    check_camera(path, "row " + std::to_string(i), c);
    cams.push_back(c);
  }
  return cams;
}

// ---------------------------------------------------------------- transforms.json

double json_number(const json& j, const std::string& source, const std::string& element, const char* key) {
  if (!j.contains(key)) throw_error(source, ": ", element, " has no '", key, "'");
  if (!j[key].is_number()) throw_error(source, ": ", element, " '", key, "' is not a number");
  const double v = j[key].get<double>();
  if (!std::isfinite(v)) throw_error(source, ": ", element, " '", key, "' is not finite");
  return v;
}


std::vector<Camera> read_transforms(const std::string& path, const CameraReadOptions& opt) {
  const json root = read_json_file(path);
  if (!root.is_object() || !root.contains("frames") || !root["frames"].is_array())
    throw_error(path, ": not a transforms file (no 'frames' list)");
  const fs::path base = fs::path(path).parent_path();
  std::vector<Camera> cams;
  const json& frames = root["frames"];
  for (size_t i = 0; i < frames.size(); ++i) {
    const json& f = frames[i];
    const std::string el = "frame " + std::to_string(i);
    auto pick = [&](const char* key) -> const json* {
      if (f.contains(key)) return &f[key];
      if (root.contains(key)) return &root[key];
      return nullptr;
    };
    Camera c;
    if (f.contains("file_path") && f["file_path"].is_string()) c.image_path = f["file_path"].get<std::string>();
    c.name = c.image_path.empty() ? "frame" + std::to_string(i) : strip_extension_and_dot(c.image_path);
    // Image size: w/h, else the image itself, else the options.
    int w = 0, h = 0;
    if (pick("w")) w = image_side(json_number(f.contains("w") ? f : root, path, el, "w"), path, el, "'w'");
    if (pick("h")) h = image_side(json_number(f.contains("h") ? f : root, path, el, "h"), path, el, "'h'");
    if ((w <= 0 || h <= 0) && !c.image_path.empty()) {
      const fs::path ip = base / c.image_path;
      for (const char* ext : {"", ".png", ".jpg", ".jpeg", ".exr"})
        if (image_size(ip.string() + ext, &w, &h)) break;
    }
    if (w <= 0 || h <= 0) {
      w = opt.width;
      h = opt.height;
    }
    if (w <= 0 || h <= 0)
      throw_error(path, ": ", el, " has no image size (no w/h, image '", c.image_path, "' not found); give the width and height");
    c.width = w;
    c.height = h;
    if (pick("fl_x")) {
      const json& src = f.contains("fl_x") ? f : root;
      c.fx = json_number(src, path, el, "fl_x");
      c.fy = pick("fl_y") ? json_number(f.contains("fl_y") ? f : root, path, el, "fl_y") : c.fx;
    } else if (pick("camera_angle_x")) {
      const double ax = json_number(f.contains("camera_angle_x") ? f : root, path, el, "camera_angle_x");
      c.fx = w / (2.0 * std::tan(ax / 2.0));
      c.fy = c.fx;
      if (pick("camera_angle_y"))
        c.fy = h / (2.0 * std::tan(json_number(f.contains("camera_angle_y") ? f : root, path, el, "camera_angle_y") / 2.0));
    } else if (pick("x_fov")) {
      const double ax = json_number(f.contains("x_fov") ? f : root, path, el, "x_fov") * kPi / 180.0;
      c.fx = c.fy = w / (2.0 * std::tan(ax / 2.0));
    } else {
      throw_error(path, ": ", el, " has no focal length (fl_x, camera_angle_x or x_fov)");
    }
    c.cx = pick("cx") ? json_number(f.contains("cx") ? f : root, path, el, "cx") : w / 2.0;
    c.cy = pick("cy") ? json_number(f.contains("cy") ? f : root, path, el, "cy") : h / 2.0;
    for (const char* k : {"k1", "k2", "p1", "p2"})
      if (const json* d = pick(k))
        if (d->is_number() && d->get<double>() != 0.0)
          throw_error(path, ": ", el, " has distortion '", k, "' = ", d->get<double>(), ", which fillgs does not undistort");
    if (!f.contains("transform_matrix") || !f["transform_matrix"].is_array() || f["transform_matrix"].size() < 3 ||
        f["transform_matrix"].size() > 4)
      throw_error(path, ": ", el, " has no 4x4 'transform_matrix'");
    Mat4d m = Mat4d::Identity();
    // A fourth row, when written (it usually is), must be [0, 0, 0, 1]: anything else is a
    // projective matrix, not a pose, and dropping it would place the camera silently wrong.
    if (f["transform_matrix"].size() == 4) {
      const json& row = f["transform_matrix"][3];
      bool affine = row.is_array() && row.size() == 4;
      for (size_t k = 0; affine && k < 4; ++k) affine = row[k].is_number() && row[k].get<double>() == (k == 3 ? 1.0 : 0.0);
      if (!affine) throw_error(path, ": ", el, " 'transform_matrix' last row is ", row.dump(), ", not [0, 0, 0, 1]");
    }
    for (int r = 0; r < 3; ++r) {
      const json& row = f["transform_matrix"][size_t(r)];
      if (!row.is_array() || row.size() < 4) throw_error(path, ": ", el, " 'transform_matrix' row ", r, " is not 4 numbers");
      for (int k = 0; k < 4; ++k) {
        if (!row[size_t(k)].is_number()) throw_error(path, ": ", el, " 'transform_matrix' [", r, "][", k, "] is not a number");
        m(r, k) = row[size_t(k)].get<double>();
      }
    }
    Mat3d c2w = m.block<3, 3>(0, 0);
    c2w.col(1) = -c2w.col(1);  // OpenGL (y up, z back) to OpenCV (y down, z forward)
    c2w.col(2) = -c2w.col(2);
    c.R = c2w.transpose();
    c.t = -c.R * m.block<3, 1>(0, 3);
    if (f.contains("time")) c.time = json_number(f, path, el, "time");
    check_camera(path, el, c);
    cams.push_back(c);
  }
  return cams;
}

// ---------------------------------------------------------------- 3DGS cameras.json

std::vector<Camera> read_gaussian_json(const std::string& path) {
  const json root = read_json_file(path);
  if (!root.is_array()) throw_error(path, ": 3DGS cameras.json must be a list");
  std::vector<Camera> cams;
  for (size_t i = 0; i < root.size(); ++i) {
    const json& e = root[i];
    const std::string el = "camera " + std::to_string(i);
    Camera c;
    if (!e.is_object()) throw_error(path, ": ", el, " is not an object");
    if (e.contains("img_name") && !e["img_name"].is_string()) throw_error(path, ": ", el, " 'img_name' is not a string");
    c.name = e.contains("img_name") ? e["img_name"].get<std::string>() : "cam" + std::to_string(i);
    c.image_path = c.name;
    c.width = image_side(json_number(e, path, el, "width"), path, el, "width");
    c.height = image_side(json_number(e, path, el, "height"), path, el, "height");
    c.fx = json_number(e, path, el, "fx");
    c.fy = json_number(e, path, el, "fy");
    c.cx = c.width / 2.0;
    c.cy = c.height / 2.0;
    auto number = [&](const json& v, const std::string& what) {
      if (!v.is_number()) throw_error(path, ": ", el, " ", what, " is not a number");
      return v.get<double>();
    };
    if (!e.contains("position") || !e["position"].is_array() || e["position"].size() != 3)
      throw_error(path, ": ", el, " needs 'position' (3 numbers)");
    if (!e.contains("rotation") || !e["rotation"].is_array() || e["rotation"].size() != 3)
      throw_error(path, ": ", el, " needs 'rotation' (3 rows of 3 numbers)");
    Vec3d pos;
    Mat3d rot;
    for (int r = 0; r < 3; ++r) {
      pos[r] = number(e["position"][size_t(r)], "'position' [" + std::to_string(r) + "]");
      const json& row = e["rotation"][size_t(r)];
      if (!row.is_array() || row.size() != 3)
        throw_error(path, ": ", el, " 'rotation' row ", r, " has ", row.is_array() ? row.size() : 0, " values, needs 3");
      for (int k = 0; k < 3; ++k) rot(r, k) = number(row[size_t(k)], "'rotation' [" + std::to_string(r) + "][" + std::to_string(k) + "]");
    }
    c.R = rot.transpose();
    c.t = -c.R * pos;
    check_camera(path, el, c);
    cams.push_back(c);
  }
  return cams;
}

// ---------------------------------------------------------------- Technicolor

std::vector<Camera> read_technicolor(const std::string& path, const CameraReadOptions& opt) {
  std::istringstream in(read_file(path));
  std::string line;
  std::getline(in, line);  // header
  std::vector<Camera> cams;
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::istringstream ls(line);
    double v[12];
    for (int k = 0; k < 12; ++k)
      if (!(ls >> v[k])) throw_error(path, ": line ", line_no, ": expected 12 numbers, found ", k);
    Camera c;
    char name[32];
    std::snprintf(name, sizeof name, "cam%02zu", cams.size());
    c.name = name;
    c.width = opt.width > 0 ? opt.width : 2048;
    c.height = opt.height > 0 ? opt.height : 1088;
    c.fx = c.fy = v[0];
    c.cx = v[1];
    c.cy = v[2];
    c.R = quat_wxyz_to_matrix(path, "line " + std::to_string(line_no), v[5], v[6], v[7], v[8]);
    c.t = Vec3d(v[9], v[10], v[11]);
    check_camera(path, "line " + std::to_string(line_no), c);
    cams.push_back(c);
  }
  if (cams.empty()) throw_error(path, ": no camera rows after the header line");
  return cams;
}

// ---------------------------------------------------------------- Dynamic 3D Gaussians (Panoptic)

/// train_meta.json / test_meta.json: w, h, and per frame f and slot i k[f][i] (3×3),
/// w2c[f][i] (4×4, OpenCV axes), fn[f][i] (image path under ims/), cam_id[f][i]. One camera
/// per (frame, slot), named "<cam_id>/<frame:06d>", time f / (F − 1), image path fn. K is
/// taken as fillgs's corner convention, as Dynamic 3D Gaussians' renderer uses it (its
/// projection puts the ray through (cx, cy) at pixel coordinate cx − ½ of a grid whose first
/// pixel centre is 0).
std::vector<Camera> read_d3dgs_meta(const std::string& path) {
  const json root = read_json_file(path);
  if (!root.is_object()) throw_error(path, ": a Dynamic 3D Gaussians meta file must be an object");
  for (const char* key : {"w", "h", "k", "w2c", "fn", "cam_id"})
    if (!root.contains(key)) throw_error(path, ": no '", key, "' (a Dynamic 3D Gaussians meta file has w, h, k, w2c, fn, cam_id)");
  const double w = json_number(root, path, "the file", "w"), h = json_number(root, path, "the file", "h");
  image_side(w, path, "the file", "w");
  image_side(h, path, "the file", "h");
  const json &K = root["k"], &W2C = root["w2c"], &FN = root["fn"], &ID = root["cam_id"];
  for (const auto& [name, list] : {std::pair<const char*, const json*>{"k", &K}, {"w2c", &W2C}, {"fn", &FN}, {"cam_id", &ID}})
    if (!list->is_array() || list->empty()) throw_error(path, ": '", name, "' is not a non-empty list of frames");
  const size_t F = FN.size();
  if (K.size() != F || W2C.size() != F || ID.size() != F)
    throw_error(path, ": the lists disagree on the number of frames (k ", K.size(), ", w2c ", W2C.size(), ", fn ", F, ", cam_id ", ID.size(), ")");
  auto id_of = [&](const json& v, const std::string& el) -> std::string {
    if (v.is_number_integer()) return std::to_string(v.get<long long>());
    if (v.is_string() && !v.get<std::string>().empty()) return v.get<std::string>();
    throw_error(path, ": ", el, " is not a camera id (an integer or a name)");
  };
  std::vector<std::string> ids0;
  std::vector<Camera> cams;
  for (size_t f = 0; f < F; ++f) {
    const std::string fe = "frame " + std::to_string(f);
    if (!FN[f].is_array() || !K[f].is_array() || !W2C[f].is_array() || !ID[f].is_array())
      throw_error(path, ": ", fe, ": k, w2c, fn and cam_id must each hold a list of cameras");
    const size_t n = FN[f].size();
    if (K[f].size() != n || W2C[f].size() != n || ID[f].size() != n)
      throw_error(path, ": ", fe, ": the lists disagree on the number of cameras (k ", K[f].size(), ", w2c ", W2C[f].size(), ", fn ", n,
                  ", cam_id ", ID[f].size(), ")");
    std::vector<std::string> ids;
    for (size_t i = 0; i < n; ++i) ids.push_back(id_of(ID[f][i], fe + " cam_id[" + std::to_string(i) + "]"));
    if (f == 0) {
      ids0 = ids;
      if (std::set<std::string>(ids.begin(), ids.end()).size() != ids.size()) throw_error(path, ": frame 0 names a camera twice");
    } else if (ids != ids0) {
      throw_error(path, ": ", fe, " has other cameras than frame 0 (", n, " against ", ids0.size(),
                  "); every camera needs every frame");
    }
    for (size_t i = 0; i < n; ++i) {
      const std::string el = fe + " camera " + ids[i];
      auto matrix = [&](const json& m, int rows, int cols, const char* what) {
        Eigen::MatrixXd out(rows, cols);
        if (!m.is_array() || m.size() != size_t(rows)) throw_error(path, ": ", el, ": ", what, " is not ", rows, "x", cols);
        for (int r = 0; r < rows; ++r) {
          if (!m[size_t(r)].is_array() || m[size_t(r)].size() != size_t(cols)) throw_error(path, ": ", el, ": ", what, " is not ", rows, "x", cols);
          for (int c = 0; c < cols; ++c) {
            const json& x = m[size_t(r)][size_t(c)];
            if (!x.is_number() || !std::isfinite(x.get<double>())) throw_error(path, ": ", el, ": ", what, "[", r, "][", c, "] is not a finite number");
            out(r, c) = x.get<double>();
          }
        }
        return out;
      };
      const Eigen::MatrixXd k = matrix(K[f][i], 3, 3, "k"), m = matrix(W2C[f][i], 4, 4, "w2c");
      Camera c;
      c.width = int(w), c.height = int(h);
      c.fx = k(0, 0), c.fy = k(1, 1), c.cx = k(0, 2), c.cy = k(1, 2);
      if (!(c.fx > 0 && c.fy > 0) || std::abs(k(0, 1)) > 1e-9 * c.fx || k(1, 0) != 0 || k(2, 0) != 0 || k(2, 1) != 0 || k(2, 2) != 1)
        throw_error(path, ": ", el, ": k is not a pinhole intrinsic matrix [fx 0 cx; 0 fy cy; 0 0 1]");
      c.R = m.block<3, 3>(0, 0);
      c.t = m.block<3, 1>(0, 3);
      if ((c.R * c.R.transpose() - Mat3d::Identity()).norm() > 1e-4 || c.R.determinant() < 0 || m(3, 0) != 0 || m(3, 1) != 0 || m(3, 2) != 0 ||
          m(3, 3) != 1)
        throw_error(path, ": ", el, ": w2c is not a rigid world-to-camera matrix [R t; 0 0 0 1]");
      if (!FN[f][i].is_string() || FN[f][i].get<std::string>().empty()) throw_error(path, ": ", el, ": fn is not a file name");
      c.image_path = FN[f][i].get<std::string>();
      char frame[24];
      std::snprintf(frame, sizeof frame, "%06zu", f);
      c.name = ids[i] + "/" + frame;
      c.time = FrameGrid(int(F)).time(int(f));
      check_camera(path, el, c);
      cams.push_back(c);
    }
  }
  return cams;
}

}  // namespace

CameraFormat detect_camera_format(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw_error(path, ": no such file or directory");
  if (fs::is_directory(path, ec)) return CameraFormat::Colmap;
  const fs::path p(path);
  const std::string name = p.filename().string(), ext = p.extension().string();
  if (name == "cameras.txt" || name == "images.txt" || name == "cameras.bin" || name == "images.bin") return CameraFormat::Colmap;
  if (ext == ".npy") return CameraFormat::Llff;
  // Dynamic 3D Gaussians names its camera files train_meta.json and test_meta.json.
  if (name.size() > 10 && name.compare(name.size() - 10, 10, "_meta.json") == 0) return CameraFormat::D3dgs;
  if (ext == ".json") {
    require_regular_file(path);
    std::ifstream in(path);
    char ch = 0;
    while (in.get(ch) && std::isspace(static_cast<unsigned char>(ch))) {}
    return ch == '[' ? CameraFormat::GaussianJson : CameraFormat::Transforms;
  }
  if (ext == ".txt") return CameraFormat::Technicolor;
  throw_error(path, ": cannot tell the camera format from the name; name the format");
}

std::vector<Camera> read_cameras(const std::string& path, const CameraReadOptions& opt) {
  const CameraFormat f = opt.format == CameraFormat::Auto ? detect_camera_format(path) : opt.format;
  std::vector<Camera> cams = reading(path, [&]() -> std::vector<Camera> {
    switch (f) {
      case CameraFormat::Colmap: return read_colmap(path);
      case CameraFormat::Llff: return read_llff(path, opt);
      case CameraFormat::Transforms: return read_transforms(path, opt);
      case CameraFormat::GaussianJson: return read_gaussian_json(path);
      case CameraFormat::Technicolor: return read_technicolor(path, opt);
      case CameraFormat::D3dgs: return read_d3dgs_meta(path);
      case CameraFormat::Auto: break;
    }
    return {};
  });
  if (cams.empty()) throw_error(path, ": no cameras");
  // Names must be unique (they become file names): disambiguate repeats by index.
  std::map<std::string, int> seen;
  for (Camera& c : cams) {
    if (c.name.find("..") != std::string::npos || (!c.name.empty() && c.name[0] == '/'))
      throw_error(path, ": camera name '", c.name, "' escapes the output folder");
    const int n = seen[c.name]++;
    if (n > 0) c.name += "_" + std::to_string(n);
  }
  return cams;
}

void write_transforms_json(const std::string& path, const std::vector<Camera>& cams) {
  json root;
  root["frames"] = json::array();
  for (const Camera& c : cams) {
    Mat3d c2w = c.R.transpose();
    c2w.col(1) = -c2w.col(1);
    c2w.col(2) = -c2w.col(2);
    const Vec3d C = c.centre();
    json m = json::array();
    for (int r = 0; r < 4; ++r) {
      json row = json::array();
      for (int k = 0; k < 4; ++k) row.push_back(r < 3 ? (k < 3 ? c2w(r, k) : C[r]) : (k == 3 ? 1.0 : 0.0));
      m.push_back(row);
    }
    json f;
    f["file_path"] = c.image_path.empty() ? c.name : c.image_path;
    f["fl_x"] = c.fx;
    f["fl_y"] = c.fy;
    f["cx"] = c.cx;
    f["cy"] = c.cy;
    f["w"] = c.width;
    f["h"] = c.height;
    if (c.has_time()) f["time"] = c.time;
    f["transform_matrix"] = m;
    root["frames"].push_back(f);
  }
  write_file_atomically(path, root.dump(2) + "\n");
}

void check_colmap_text_target(const std::string& dir) {
  // COLMAP and fillgs read a folder's binary model before its text one: text cameras
  // written beside cameras.bin or images.bin would never be read back.
  for (const char* binary : {"cameras.bin", "images.bin"}) {
    std::error_code ec;
    if (std::filesystem::exists(join_path(dir, binary), ec))
      throw_error(join_path(dir, binary), ": the folder holds a binary COLMAP model, which readers take before the text one this would write; "
                                          "write elsewhere or remove the .bin files");
  }
}

void write_colmap_text(const std::string& dir, const std::vector<Camera>& cams) {
  check_colmap_text_target(dir);
  make_directories(dir);
  std::ostringstream cs, is;
  cs.precision(17);
  is.precision(17);
  cs << "# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n";
  is << "# Image list with two lines of data per image:\n#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
        "#   POINTS2D[] as (X, Y, POINT3D_ID)\n";
  for (size_t i = 0; i < cams.size(); ++i) {
    const Camera& c = cams[i];
    cs << i + 1 << " PINHOLE " << c.width << " " << c.height << " " << c.fx << " " << c.fy << " " << c.cx << " " << c.cy << "\n";
    const Vec4d q = matrix_to_quat(c.R);
    std::string name = c.image_path.empty() ? c.name + ".png" : c.image_path;
    if (name.rfind("./", 0) == 0) name = name.substr(2);
    is << i + 1 << " " << q[0] << " " << q[1] << " " << q[2] << " " << q[3] << " " << c.t[0] << " " << c.t[1] << " "
       << c.t[2] << " " << i + 1 << " " << name << "\n\n";
  }
  write_file_atomically(join_path(dir, "cameras.txt"), cs.str());
  write_file_atomically(join_path(dir, "images.txt"), is.str());
  write_file_atomically(join_path(dir, "points3D.txt"), "# 3D point list (empty)\n");
}

nlohmann::json camera_json(const Camera& c) {
  const Mat4d c2w = c.camera_to_world();
  nlohmann::json m = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) m.push_back({c2w(r, 0), c2w(r, 1), c2w(r, 2), c2w(r, 3)});
  return {{"name", c.name}, {"width", c.width}, {"height", c.height}, {"fx", c.fx}, {"fy", c.fy}, {"cx", c.cx}, {"cy", c.cy},
          {"time", c.time}, {"camera_to_world_opencv", m}};
}

Camera camera_from_json(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object()) throw_error(where, ": a camera must be a JSON object");
  auto number = [&](const char* key) {
    const auto it = j.find(key);
    if (it == j.end() || !it->is_number()) throw_error(where, ": camera field '", key, "' is missing or not a number");
    return it->get<double>();
  };
  Camera c;
  if (j.contains("name") && j["name"].is_string()) c.name = j["name"].get<std::string>();
  const double w = number("width"), h = number("height");
  if (!(w >= 1 && h >= 1 && w <= 1 << 16 && h <= 1 << 16 && w == std::floor(w) && h == std::floor(h)))
    throw_error(where, ": camera '", c.name, "' has size ", w, "x", h, " (must be whole numbers from 1 to 65536)");
  c.width = int(w), c.height = int(h);
  c.fx = number("fx"), c.fy = number("fy"), c.cx = number("cx"), c.cy = number("cy");
  if (!(c.fx > 0 && c.fy > 0 && std::isfinite(c.fx) && std::isfinite(c.fy) && std::isfinite(c.cx) && std::isfinite(c.cy)))
    throw_error(where, ": camera '", c.name, "' has focal lengths ", c.fx, ", ", c.fy, " (must be positive and finite)");
  if (j.contains("time") && j["time"].is_number()) c.time = j["time"].get<double>();
  const auto m = j.find("camera_to_world_opencv");
  if (m == j.end() || !m->is_array() || m->size() != 4) throw_error(where, ": camera '", c.name, "' needs camera_to_world_opencv, 4 rows");
  Mat4d c2w;
  for (int r = 0; r < 4; ++r) {
    const nlohmann::json& row = (*m)[size_t(r)];
    if (!row.is_array() || row.size() != 4) throw_error(where, ": camera '", c.name, "': camera_to_world_opencv row ", r, " is not 4 numbers");
    for (int k = 0; k < 4; ++k) {
      if (!row[size_t(k)].is_number()) throw_error(where, ": camera '", c.name, "': camera_to_world_opencv row ", r, " is not 4 numbers");
      c2w(r, k) = row[size_t(k)].get<double>();
    }
  }
  const Mat3d rot = c2w.topLeftCorner<3, 3>();
  if (!c2w.allFinite() || (rot.transpose() * rot - Mat3d::Identity()).norm() > 1e-6 || rot.determinant() < 0)
    throw_error(where, ": camera '", c.name, "': camera_to_world_opencv is not a rigid transform");
  c.R = rot.transpose();
  c.t = -c.R * c2w.topRightCorner<3, 1>();
  return c;
}

}  // namespace fillgs
