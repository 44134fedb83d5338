// libFuzzer harness for one fillgs reader (tests/README.md, "Robustness"). Compiled once and linked
// into one executable per reader, fuzz_<reader>, whose name picks the reader; every harness writes the input to files in its own
// temporary folder and reads them back the way the command line does.
//
// The contract a harness enforces: any input either reads, or fails with a fillgs::Error
// (one line naming the file). Another exception escaping is a finding (a message that names
// nothing), and so are crashes, sanitizer reports, leaks, timeouts and out-of-memory.
//
// Inputs of formats made of several files (COLMAP, the Ex4DGS pair) are split at the byte
// string kSplit: part 0 is the first file, part 1 the second, and so on.
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "fillgs/model/camera.hpp"
#include "fillgs/io/array_input.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/io/npy.hpp"
#include "fillgs/io/ply.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/io/torch_file.hpp"
#include "fillgs/train/train.hpp"
#include "../torch_craft.hpp"

namespace fs = std::filesystem;
using namespace fillgs;

namespace {

const std::string kSplit("\0FILLGS-SPLIT\0", 14);

std::vector<std::string> split(const std::string& data, size_t parts) {
  std::vector<std::string> out;
  size_t from = 0;
  while (out.size() + 1 < parts) {
    const size_t at = data.find(kSplit, from);
    if (at == std::string::npos) break;
    out.push_back(data.substr(from, at - from));
    from = at + kSplit.size();
  }
  out.push_back(data.substr(from));
  while (out.size() < parts) out.emplace_back();
  return out;
}

const std::string& work_dir() {
  static const std::string dir = [] {
    const fs::path d = fs::temp_directory_path() / ("fillgs_fuzz_" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d.string();
  }();
  return dir;
}

std::string put(const std::string& name, const std::string& bytes) {
  const std::string path = join_path(work_dir(), name);
  fs::create_directories(fs::path(path).parent_path());
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) std::abort();
  std::fwrite(bytes.data(), 1, bytes.size(), f);
  std::fclose(f);
  return path;
}

/// The reader this executable fuzzes: its name without "fuzz_" (set by LLVMFuzzerInitialize).
std::string kReader;

/// One 8×6 view, for the checkpoint reader (a checkpoint is read against its dataset).
const Dataset& tiny_dataset() {
  static const Dataset dataset = [] {
    Image im(8, 6, 3);
    for (size_t i = 0; i < im.pixels.size(); ++i) im.pixels[i] = float(i % 7) / 7.0f;
    write_image(join_path(work_dir(), "ds/cam0.png"), im);
    put("ds/transforms.json",
        R"({"camera_angle_x": 1.0, "frames": [{"file_path": "cam0.png", "w": 8, "h": 6,
            "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]}]})");
    return Dataset::load(join_path(work_dir(), "ds"), join_path(work_dir(), "ds/transforms.json"));
  }();
  return dataset;
}

void read_one(const std::string& data) {
  const std::string& r = kReader;
  if (r == "ply_3dgs" || r == "ply_fillgs" || r == "ply_stg") {
    SceneReadOptions o;
    o.format = r == "ply_3dgs" ? "3dgs" : r == "ply_fillgs" ? "fillgs" : "stg";
    read_scene(put("scene.ply", data), o);
  } else if (r == "ex4dgs") {
    const std::vector<std::string> p = split(data, 3);
    put("ex4dgs/point_cloud/iteration_1/point_cloud.ply", p[0]);
    put("ex4dgs/point_cloud/iteration_1/dynamic_point_cloud.ply", p[1]);
    put("ex4dgs/cfg_args", p[2]);
    SceneReadOptions o;
    o.format = "ex4dgs";
    read_scene(join_path(work_dir(), "ex4dgs/point_cloud/iteration_1/point_cloud.ply"), o);
  } else if (r == "npy") {
    const std::string path = put("array.npy", data);
    read_npy(path).to_doubles(path);
  } else if (r == "llff") {
    read_cameras(put("poses_bounds.npy", data), {CameraFormat::Llff});
  } else if (r == "colmap_text" || r == "colmap_bin") {
    const std::vector<std::string> p = split(data, 2);
    const std::string ext = r == "colmap_text" ? ".txt" : ".bin";
    put("colmap/cameras" + ext, p[0]);
    put("colmap/images" + ext, p[1]);
    // The other kind may be left from a run of the other harness: keep only this one.
    std::error_code ec;
    fs::remove(join_path(work_dir(), std::string("colmap/cameras") + (ext == ".txt" ? ".bin" : ".txt")), ec);
    read_cameras(join_path(work_dir(), "colmap"), {CameraFormat::Colmap});
  } else if (r == "transforms") {
    CameraReadOptions o{CameraFormat::Transforms};
    o.width = 64, o.height = 48;
    read_cameras(put("transforms.json", data), o);
  } else if (r == "cameras_json") {
    read_cameras(put("cameras.json", data), {CameraFormat::GaussianJson});
  } else if (r == "technicolor") {
    read_cameras(put("cameras_parameters.txt", data), {CameraFormat::Technicolor});
  } else if (r == "d3dgs") {
    read_cameras(put("train_meta.json", data), {CameraFormat::D3dgs});
  } else if (r == "points") {
    read_points(put("points3D.bin", data));
  } else if (r == "colour_correction") {
    read_colour_correction(put("colour_correction.json", data));
  } else if (r == "python_arrays") {  // what the Python module builds from NumPy arrays (io/array_input.hpp)
    // Bytes as the arrays: K [9] and world_to_camera [16] float32, width, height, time float64;
    // then n (a byte, at most 16 Gaussians), the SH coefficients per Gaussian (a byte), and
    // the Gaussians' float32 values (zeros where the input ends).
    std::string b = data;
    const size_t camera_bytes = 25 * 4 + 3 * 8;
    if (b.size() < camera_bytes + 2) b.resize(camera_bytes + 2, '\0');
    float K[9], M[16];
    double size_time[3];
    std::memcpy(K, b.data(), sizeof K);
    std::memcpy(M, b.data() + sizeof K, sizeof M);
    std::memcpy(size_time, b.data() + sizeof K + sizeof M, sizeof size_time);
    try {
      camera_from_arrays(K, M, size_time[0], size_time[1], size_time[2], "cam0", 0);
    } catch (const Error&) {
    }
    const size_t n = size_t(uint8_t(b[camera_bytes])) % 17, coefficients = size_t(uint8_t(b[camera_bytes + 1])) % 20;
    std::vector<float> v((n * (3 + 3 + 4 + 1) + n * coefficients * 3), 0.0f);
    if (!v.empty()) std::memcpy(v.data(), b.data() + camera_bytes + 2, std::min(v.size() * 4, b.size() - camera_bytes - 2));
    const float* at = v.data();
    gaussians_from_arrays(n, at, at + n * 3, at + n * 6, at + n * 10, coefficients ? at + n * 11 : nullptr, coefficients, "arrays");
  } else if (r == "image") {  // what a refiner hands back
    read_image(put("refined.png", data));
  } else if (r == "image_jpeg") {  // what datasets hold (Panoptic's ims/<camera>/<frame>.jpg)
    read_image(put("000000.jpg", data));
  } else if (r == "pickle") {
    PickleValues v;
    run_pickle(data, "data.pkl", v);
  } else if (r == "pth") {
    const TorchFile tf(put("model.pth", data));
    for (size_t i = 0; i < tf.value_count(); ++i)
      if (tf.kind(PickleValues::Ref(i)) == PickleValues::Kind::Tensor) tf.tensor(PickleValues::Ref(i), "tensor");
  } else if (r == "npz_dynamic3dgs") {
    SceneReadOptions o;
    o.format = "dynamic3dgs";
    read_scene(put("d3dgs/params.npz", data), o);
  } else if (r == "ed3dgs" || r == "4dgaussians") {
    const std::vector<std::string> p = split(data, 3);
    const std::string run = r + "_run";
    put(run + "/point_cloud/iteration_100/point_cloud.ply", p[0]);
    put(run + "/point_cloud/iteration_100/deformation.pth", p[1]);
    put(run + "/cfg_args", p[2]);
    SceneReadOptions o;
    o.format = r == "ed3dgs" ? "e-d3dgs" : "4dgaussians";
    o.model_frames = r == "ed3dgs" ? 0 : 3;
    read_scene(join_path(work_dir(), run), o);
  } else if (r == "deformable3dgs") {
    const std::vector<std::string> p = split(data, 3);
    put("deformable_run/point_cloud/iteration_100/point_cloud.ply", p[0]);
    put("deformable_run/deform/iteration_100/deform.pth", p[1]);
    put("deformable_run/cfg_args", p[2]);
    SceneReadOptions o;
    o.format = "deformable3dgs";
    o.model_frames = 3;
    read_scene(join_path(work_dir(), "deformable_run"), o);
  } else if (r == "4dgs") {
    SceneReadOptions o;
    o.format = "4dgs";
    o.model_frames = 3;
    o.model_time_range = "0:1";
    read_scene(put("4dgs/chkpnt100.pth", data), o);
  } else if (r == "ply_frames") {
    const std::vector<std::string> p = split(data, 2);
    put("frames/time_00000.ply", p[0]);
    put("frames/time_00001.ply", p[1]);
    SceneReadOptions o;
    o.format = "ply-frames";
    read_scene(join_path(work_dir(), "frames"), o);
  } else if (r == "checkpoint") {
    TrainOptions o;
    o.iterations = 1;
    Trainer::resume(tiny_dataset(), put("latest.ckpt", data), o);
  } else {
    std::abort();  // an executable named for no reader is a build error, not a finding
  }
}

// ---- seeds: one small valid input per reader, written with fillgs's own writers where it
// has them (FILLGS_FUZZ_SEEDS=DIR fuzz_<reader> writes DIR/seed_* and exits) ----

void add_column(PlyElement& e, const std::string& name, std::vector<float> values) {
  e.property_names.push_back(name);
  e.columns.push_back(std::move(values));
}

PlyElement gaussians(size_t n, const std::string& prefix = "", bool xyz = true, bool rot = true) {
  PlyElement e;
  e.name = "vertex";
  e.count = n;
  auto col = [&](float a, float b) {
    std::vector<float> v(n);
    for (size_t i = 0; i < n; ++i) v[i] = a + b * float(i);
    return v;
  };
  if (xyz)
    for (const char* k : {"x", "y", "z"}) add_column(e, k, col(0.1f, 0.5f));
  for (int c = 0; c < 3; ++c) add_column(e, prefix + "f_dc_" + std::to_string(c), col(0.2f * c, 0.1f));
  add_column(e, prefix + "opacity", col(1.0f, 0.0f));
  for (int a = 0; a < 3; ++a) add_column(e, prefix + "scale_" + std::to_string(a), col(-3.0f, 0.1f));
  if (rot)
    for (int a = 0; a < 4; ++a) add_column(e, "rot_" + std::to_string(a), col(a == 0 ? 1.0f : 0.0f, 0.0f));
  return e;
}

PlyData ply_of(std::vector<PlyElement> elements, PlyFormat format) {
  PlyData d;
  d.format = format;
  d.elements = std::move(elements);
  return d;
}


std::string stg_ply(PlyFormat format) {
  PlyElement v = gaussians(2);
  add_column(v, "trbf_center", {0.5f, 0.5f});
  add_column(v, "trbf_scale", {-1.4f, 6.9f});
  for (int k = 0; k < 9; ++k) add_column(v, "motion_" + std::to_string(k), {float(k % 3), 0.0f});
  for (int k = 0; k < 4; ++k) add_column(v, "omega_" + std::to_string(k), {k == 1 ? 0.4f : 0.0f, 0.0f});
  const std::string path = join_path(work_dir(), "seed_stg.ply");
  write_ply(path, ply_of({v}, format));
  return path;
}

void make_seeds(const std::string& dir) {
  fs::create_directories(dir);
  auto seed = [&](const std::string& name, const std::string& bytes) { write_file_atomically(join_path(dir, name), bytes); };
  const std::string& r = kReader;
  const std::string tmp = join_path(work_dir(), "seedtmp");
  if (r == "ply_3dgs") {
    for (PlyFormat f : {PlyFormat::Ascii, PlyFormat::BinaryLittleEndian, PlyFormat::BinaryBigEndian}) {
      write_ply(tmp, ply_of({gaussians(3)}, f));
      seed("seed_" + std::to_string(int(f)) + ".ply", read_file(tmp));
    }
  } else if (r == "ply_stg") {
    seed("seed_ascii.ply", read_file(stg_ply(PlyFormat::Ascii)));
    seed("seed_binary.ply", read_file(stg_ply(PlyFormat::BinaryLittleEndian)));
  } else if (r == "ply_fillgs") {
    SceneReadOptions o;
    o.format = "stg";
    write_fillgs_ply(tmp + ".ply", read_scene(stg_ply(PlyFormat::BinaryLittleEndian), o), 3);
    seed("seed.ply", read_file(tmp + ".ply"));
  } else if (r == "ex4dgs") {
    PlyElement sv = gaussians(2);
    for (int a = 0; a < 3; ++a) add_column(sv, "xyz_disp_" + std::to_string(a), {0.0f, a == 0 ? 2.1f : 0.0f});
    PlyElement dv = gaussians(1, "motion_", false, false);
    for (int k = 0; k < 4; ++k) {
      for (int j = 0; j < 3; ++j) add_column(dv, "motion_xyz_" + std::to_string(k) + "_" + std::to_string(j), {float(k * j)});
      for (int j = 0; j < 4; ++j) add_column(dv, "motion_rot_" + std::to_string(k) + "_" + std::to_string(j), {j == 0 ? 1.0f : 0.0f});
    }
    for (const char* n : {"motion_opacity_c_0", "motion_opacity_c_1", "motion_opacity_v_0", "motion_opacity_v_1"}) add_column(dv, n, {1.0f});
    write_ply(tmp + "s", ply_of({sv}, PlyFormat::BinaryLittleEndian));
    write_ply(tmp + "d", ply_of({dv}, PlyFormat::BinaryLittleEndian));
    seed("seed", read_file(tmp + "s") + kSplit + read_file(tmp + "d") + kSplit +
                     "Namespace(duration=21, time_interval=5, time_pad=2, interp_type='cube', var_pad=3)");
  } else if (r == "npy" || r == "llff") {
    // Two cameras of an LLFF rig: [R | t | hwf] row-major (down-right-back), then near, far.
    const double rows[2][17] = {{0, 1, 0, 0, 480, 1, 0, 0, 0, 640, 0, 0, 1, 3, 500, 0.5, 10},
                                {0, 1, 0, 0.2, 480, 1, 0, 0, 0, 640, 0, 0, 1, 3, 500, 0.5, 10}};
    write_npy(tmp + ".npy", &rows[0][0], {2, 17});
    seed("seed_f8.npy", read_file(tmp + ".npy"));
    if (r == "npy") {
      const float f[6] = {1, 2, 3, 4, 5, 6};
      write_npy(tmp + ".npy", f, {3, 2});
      seed("seed_f4.npy", read_file(tmp + ".npy"));
      const uint8_t u[4] = {1, 2, 3, 4};
      write_npy(tmp + ".npy", u, {4});
      seed("seed_u1.npy", read_file(tmp + ".npy"));
    }
  } else if (r == "colmap_text" || r == "transforms") {
    std::vector<Camera> cams(2);
    for (size_t i = 0; i < 2; ++i) {
      Camera& c = cams[i];
      c.name = "cam" + std::to_string(i);
      c.image_path = c.name + ".png";
      c.width = 64, c.height = 48, c.fx = c.fy = 50, c.cx = 32, c.cy = 24;
      c.R = Mat3d::Identity();
      c.t = Vec3d(0.1 * double(i), 0, 3);
      c.time = 0.5 * double(i);
    }
    if (r == "colmap_text") {
      write_colmap_text(tmp + "_colmap", cams);
      seed("seed", read_file(tmp + "_colmap/cameras.txt") + kSplit + read_file(tmp + "_colmap/images.txt"));
    } else {
      write_transforms_json(tmp + ".json", cams);
      seed("seed.json", read_file(tmp + ".json"));
    }
  } else if (r == "colmap_bin") {
    auto pod = [](std::string& s, auto v) { s.append(reinterpret_cast<const char*>(&v), sizeof v); };
    std::string cb, ib;
    pod(cb, uint64_t(1)), pod(cb, int32_t(1)), pod(cb, int32_t(1)), pod(cb, uint64_t(64)), pod(cb, uint64_t(48));
    for (double v : {50.0, 50.0, 32.0, 24.0}) pod(cb, v);
    pod(ib, uint64_t(1)), pod(ib, int32_t(1));
    for (double v : {1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 3.0}) pod(ib, v);
    pod(ib, int32_t(1));
    ib += std::string("cam0.png") + '\0';
    pod(ib, uint64_t(1));
    pod(ib, 1.0), pod(ib, 2.0), pod(ib, int64_t(-1));
    seed("seed", cb + kSplit + ib);
  } else if (r == "cameras_json") {
    seed("seed.json", R"([{"id": 0, "img_name": "cam0", "width": 64, "height": 48, "fx": 50, "fy": 50,
      "position": [0, 0, -3], "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}])");
  } else if (r == "technicolor") {
    seed("seed.txt", "f cx cy ar skew qw qx qy qz tx ty tz\n500 1024 544 1 0 1 0 0 0 0 0 3\n500 1024 544 1 0 1 0 0 0 0.1 0 3\n");
  } else if (r == "d3dgs") {
    seed("seed.json", R"({"w": 64, "h": 48, "k": [[[[50,0,32],[0,50,24],[0,0,1]]], [[[50,0,32],[0,50,24],[0,0,1]]]],
      "w2c": [[[[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]], [[[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]]],
      "fn": [["0/000000.jpg"], ["0/000001.jpg"]], "cam_id": [[0], [0]]})");
  } else if (r == "points") {
    auto pod = [](std::string& s, auto v) { s.append(reinterpret_cast<const char*>(&v), sizeof v); };
    std::string b;
    pod(b, uint64_t(2));
    for (int i = 0; i < 2; ++i) {
      pod(b, uint64_t(i + 1));
      for (double v : {0.1 * i, 0.2, 0.3}) pod(b, v);
      for (uint8_t v : {uint8_t(200), uint8_t(100), uint8_t(50)}) pod(b, v);
      pod(b, 0.5), pod(b, uint64_t(1)), pod(b, int32_t(1)), pod(b, int32_t(i));
    }
    seed("seed.bin", b);
  } else if (r == "python_arrays") {
    std::string b;
    auto pod = [&b](auto v) { b.append(reinterpret_cast<const char*>(&v), sizeof v); };
    for (float v : {100.0f, 0.0f, 32.0f, 0.0f, 100.0f, 24.0f, 0.0f, 0.0f, 1.0f}) pod(v);
    for (float v : {1.0f, 0.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 0.0f, 1.0f, 4.0f, 0.0f, 0.0f, 0.0f, 1.0f}) pod(v);
    for (double v : {64.0, 48.0, 0.5}) pod(v);
    pod(uint8_t(2)), pod(uint8_t(4));
    for (float v : {0.0f, 0.0f, 3.0f, 0.1f, 0.0f, 3.0f}) pod(v);                          // means [2,3]
    for (int k = 0; k < 6; ++k) pod(-3.0f);                                               // log_scales [2,3]
    for (float v : {1.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 1.0f}) pod(v);              // quaternions [2,4]
    for (float v : {0.5f, -0.5f}) pod(v);                                                 // opacity_logits [2]
    for (int k = 0; k < 2 * 4 * 3; ++k) pod(0.1f * float(k % 5));
    seed("seed.bin", b);
  } else if (r == "colour_correction") {
    seed("seed.json", R"({"cam00": {"gain": [1.1, 0.9, 1.0], "offset": [0.01, 0.0, -0.02]}, "cam01": {"gain": [1, 1, 1], "offset": [0, 0, 0]}})");
  } else if (r == "image") {
    Image im(5, 4, 3);
    for (size_t i = 0; i < im.pixels.size(); ++i) im.pixels[i] = float(i % 11) / 11.0f;
    write_image(tmp + ".png", im);
    seed("seed.png", read_file(tmp + ".png"));
  } else if (r == "image_jpeg") {
    Image im(16, 8, 3);
    for (size_t i = 0; i < im.pixels.size(); ++i) im.pixels[i] = float(i % 13) / 13.0f;
    write_image(tmp + ".jpg", im);
    seed("seed.jpg", read_file(tmp + ".jpg"));
  } else if (r == "pickle" || r == "pth" || r == "npz_dynamic3dgs" || r == "ed3dgs" || r == "4dgaussians" || r == "4dgs" ||
             r == "ply_frames" || r == "deformable3dgs") {
    // Files only PyTorch / NumPy write: the tiny models tests/make_model_fixtures.py saves
    // (bench/fuzz runs it and sets FILLGS_MODEL_FIXTURES).
    const char* env = std::getenv("FILLGS_MODEL_FIXTURES");
    if (!env) throw Error("FILLGS_MODEL_FIXTURES is not set (bench/fuzz sets it)");
    const std::string f = join_path(env, "fuzz");
    auto pth_of = [&](const std::string& run) { return read_file(join_path(f, run + "/point_cloud/iteration_100/deformation.pth")); };
    if (r == "pickle") {
      for (const char* run : {"ed3dgs", "4dgaussians"}) {
        const ZipArchive z(join_path(f, std::string(run) + "/point_cloud/iteration_100/deformation.pth"));
        for (const std::string& n : z.names())
          if (n.size() > 9 && n.compare(n.size() - 9, 9, "/data.pkl") == 0) seed(std::string("seed_") + run + ".pkl", z.read(n));
      }
      const ZipArchive z(join_path(f, "4dgs/chkpnt100.pth"));
      for (const std::string& n : z.names())
        if (n.size() > 9 && n.compare(n.size() - 9, 9, "/data.pkl") == 0) seed("seed_4dgs.pkl", z.read(n));
      // A pickle of ten thousand values (the amplification case, small).
      test::Pickle p;
      p.op(']');
      for (int k = 0; k < 10000; ++k) p.op('N').op('a');
      seed("seed_list.pkl", p.op('.').b);
    } else if (r == "pth") {
      seed("seed_ed3dgs.pth", pth_of("ed3dgs"));
      seed("seed_4dgs.pth", read_file(join_path(f, "4dgs/chkpnt100.pth")));
      // The hostile round's crafted archives (tests/test_hostile.cpp): extents that wrap
      // around 2^64, a storage declaring 2^40 elements, views of one deflated storage.
      const int64_t big = int64_t(1) << 62;
      const std::string st = test::float_storage(9);
      seed("seed_wrap_sum.pth", test::craft_pth({{"w", "0", 9, 0, {2, 2, 2, 2}, {big, big, big, big}}}, {{"0", st}}));
      seed("seed_wrap_offset.pth", test::craft_pth({{"w", "0", 9, 3, {3}, {INT64_MAX}}}, {{"0", st}}));
      seed("seed_declared.pth", test::craft_pth({{"w", "0", int64_t(1) << 40, 0, {3}, {4}}}, {{"0", st}}));
      std::vector<test::CraftTensor> views;
      for (int k = 0; k < 64; ++k) views.push_back({"w" + std::to_string(k), "0", 4096, k, {64}, {0}});
      seed("seed_views.pth", test::craft_pth(views, {{"0", std::string(4096 * 4, '\0')}}, true));
    } else if (r == "npz_dynamic3dgs") {
      seed("seed.npz", read_file(join_path(f, "dynamic3dgs/params.npz")));
    } else if (r == "ed3dgs" || r == "4dgaussians") {
      seed("seed", read_file(join_path(f, r + "/point_cloud/iteration_100/point_cloud.ply")) + kSplit + pth_of(r) + kSplit +
                       read_file(join_path(f, r + "/cfg_args")));
      // The NaN-index cases: a time offset of 3e38, an aabb of extent 1e-45.
      const std::string hostile = r == "ed3dgs" ? "hostile_offsets_huge" : "hostile_aabb";
      seed("seed_" + hostile, read_file(join_path(f, r + "/point_cloud/iteration_100/point_cloud.ply")) + kSplit + pth_of(hostile) + kSplit +
                                  read_file(join_path(f, r + "/cfg_args")));
    } else if (r == "deformable3dgs") {
      seed("seed", read_file(join_path(f, "deformable3dgs/point_cloud/iteration_100/point_cloud.ply")) + kSplit +
                       read_file(join_path(f, "deformable3dgs/deform/iteration_100/deform.pth")) + kSplit + read_file(join_path(f, "deformable3dgs/cfg_args")));
    } else if (r == "4dgs") {
      seed("seed.pth", read_file(join_path(f, "4dgs/chkpnt100.pth")));
      seed("seed_degree_nan.pth", read_file(join_path(f, "hostile_4dgs_degree_nan/chkpnt100.pth")));
      seed("seed_degree_huge.pth", read_file(join_path(f, "hostile_4dgs_degree_huge/chkpnt100.pth")));
    } else {
      seed("seed", read_file(join_path(f, "ply_frames/time_00000.ply")) + kSplit + read_file(join_path(f, "ply_frames/time_00001.ply")));
    }
  } else if (r == "checkpoint") {
    PointSet points;
    points.positions = {Vec3f(0, 0, 0), Vec3f(0.2f, 0, 0.1f), Vec3f(0, 0.2f, -0.1f), Vec3f(0.1f, 0.1f, 0)};
    points.colours.assign(4, Vec3f(0.5f, 0.4f, 0.3f));
    TrainOptions o;
    o.iterations = 1;
    Trainer t(tiny_dataset(), init_from_points(points), o);
    t.step();
    t.save_checkpoint(join_path(dir, "seed.ckpt"));
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
  // One object file serves every harness: the executable's name says which reader it is.
  const std::string self = *argc > 0 ? fs::path((*argv)[0]).filename().string() : "";
  if (self.rfind("fuzz_", 0) != 0) {
    std::fprintf(stderr, "fuzz harness: run it as fuzz_<reader> (got '%s')\n", self.c_str());
    std::exit(1);
  }
  kReader = self.substr(5);
  if (const char* dir = std::getenv("FILLGS_FUZZ_SEEDS")) {
    try {
      make_seeds(dir);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "fuzz_%s: cannot write seeds: %s\n", kReader.c_str(), e.what());
      std::exit(1);
    }
    std::exit(0);
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* bytes, size_t size) {
  try {
    read_one(std::string(reinterpret_cast<const char*>(bytes), size));
  } catch (const Error&) {
    // The expected outcome for bad input: one line naming the file.
  }
  return 0;
}
