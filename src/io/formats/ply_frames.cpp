// A folder of per-frame 3DGS PLYs (time_00000.ply ..., 4DGaussians' export_perframe_3DGS.py;
// frame_0000.ply ..., fillgs convert --to frames; viewer sequences), sampled into keys.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/io/model_formats.hpp"
#include "fillgs/io/ply.hpp"
#include "fillgs/io/torch_file.hpp"
#include "fillgs/model/sh.hpp"
#include "io/model_support.hpp"
#include "io/ply_gaussians.hpp"

namespace fillgs::model_io {

namespace {

class PlyFrames : public FrameSequence {
 public:
  PlyFrames(const std::string& dir, const SceneReadOptions&) {
    source = dir;
    const std::vector<std::string> files = frame_files(dir);
    if (files.empty()) throw_error(dir, ": no frame PLYs (time_*.ply or frame_*.ply)");
    for (const std::string& f : files) {
      const PlyData ply = read_ply(f);
      const PlyElement& v = ply.element("vertex");
      frames_.push_back(read_vertex_state(v, notes));
      const ModelState& s = frames_.back();
      if (s.size() != frames_[0].size())
        throw_error(f, ": ", s.size(), " Gaussians, the first frame (", files[0], ") has ", frames_[0].size(), "; frames must hold the same Gaussians in the same order");
      if (s.sh_degree != frames_[0].sh_degree) throw_error(f, ": SH degree ", s.sh_degree, ", the first frame has ", frames_[0].sh_degree);
    }
    finish_times();
  }

  /// time_00000.ply … (4DGaussians' export) or frame_0000.ply … (fillgs convert --to frames),
  /// in numeric order; the numbers must run 0, 1, 2, … without gaps.
  static std::vector<std::string> frame_files(const std::string& dir) {
    std::error_code ec;
    std::map<long, std::string> by_index;
    std::string prefix;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      const std::string n = e.path().filename().string();
      for (const char* p : {"time_", "frame_"}) {
        const std::string ps(p);
        if (n.rfind(ps, 0) != 0 || n.size() <= ps.size() + 4 || n.compare(n.size() - 4, 4, ".ply") != 0) continue;
        const std::string digits = n.substr(ps.size(), n.size() - ps.size() - 4);
        if (digits.empty() || digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
        if (!prefix.empty() && prefix != ps) throw_error(dir, ": holds both ", prefix, "*.ply and ", ps, "*.ply frames");
        prefix = ps;
        const auto [at, fresh] = by_index.emplace(std::stol(digits), e.path().string());
        if (!fresh)
          throw_error(dir, ": ", fs::path(at->second).filename().string(), " and ", n, " are both frame ", at->first,
                      "; keep one (fillgs will not choose)");
      }
    }
    std::vector<std::string> out;
    long expect = 0;
    for (const auto& [i, p] : by_index) {
      if (i != expect) throw_error(dir, ": frame ", expect, " missing (the next file is ", fs::path(p).filename().string(), ")");
      out.push_back(p);
      ++expect;
    }
    return out;
  }
};

}  // namespace

const ModelFormat& row_ply_frames() {
  static const ModelFormat row{{"ply-frames", {}, "per-frame 3DGS PLYs: a folder of time_*.ply or frame_*.ply numbered from 0", 60, {}},
      [](const FormatProbe& p) { return p.directory() && !PlyFrames::frame_files(p.path()).empty(); },
      [](const std::string& path, const SceneReadOptions& o) -> std::unique_ptr<TrainedModel> { return std::make_unique<PlyFrames>(path, o); },
      false, nullptr};
  return row;
}

}  // namespace fillgs::model_io
