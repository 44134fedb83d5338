// fillgs eval: PSNR, SSIM and moving-region PSNR of a model per split.
#include <optional>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "commands.hpp"
#include "options.hpp"
#include "progress_bar.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/experiment/evaluate.hpp"
#include "fillgs/experiment/experiment.hpp"
#include "fillgs/method/finetune.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/experiment/reports.hpp"
#include "fillgs/io/scene_io.hpp"


namespace fs = std::filesystem;

namespace fillgs::cli {

namespace {

// ------------------------------------------------------------------ eval

struct EvalFlags {
  std::string model, images, out, truth, lpips, colour_correction;
  std::vector<std::string> cameras, splits;
  int view_stride = 1;
  bool no_renders = false, ls_gain = false, affine_fit = false;
  DatasetOptions data;
  SceneReadOptions read;
};

int eval(const EvalFlags& f, const Invocation& in) {
  const GaussianCloud model = read_scene_shown(f.model, f.read, in);
  const std::vector<std::string>& files = f.cameras;
  std::vector<std::string> names = f.splits;
  if (names.empty())
    for (const std::string& file : files) names.push_back(fs::path(file).stem().string());
  if (names.size() != files.size()) in.fail(names.size(), " --splits names for ", files.size(), " camera files");
  std::vector<Dataset> splits;
  TerminalProgress loading(in.err, in.progress());
  for (const std::string& file : files) splits.push_back(Dataset::load(f.images, file, f.data, loading));
  std::unique_ptr<GaussianCloud> truth;
  if (in.given("--truth")) truth = std::make_unique<GaussianCloud>(read_scene_shown(f.truth, f.read, in));
  EvalOptions eo;
  eo.view_stride = f.view_stride;
  eo.truth = truth.get();
  eo.lpips_onnx = f.lpips;
  if (in.given("--colour-correction")) eo.colour = read_colour_correction(f.colour_correction);
  eo.ls_gain = f.ls_gain;
  eo.affine_fit = f.affine_fit;
  if (!eo.lpips_onnx.empty() && !fs::exists(eo.lpips_onnx)) in.fail("--lpips ", eo.lpips_onnx, " does not exist");
  std::optional<OutputFolder> folder;  // a failed or killed run leaves the folder as it was
  if (!f.out.empty()) folder.emplace(f.out);
  TerminalProgress progress(in.err, in.progress());
  std::vector<SplitMetrics> metrics;
  in.out << "split            views   PSNR    SSIM   moving PSNR" << (eo.lpips_onnx.empty() ? "" : "   LPIPS")
      << (eo.ls_gain ? "   PSNR (least-squares gain per image)" : "") << (eo.affine_fit ? "   PSNR (affine colour fit per image)" : "") << "\n";
  for (size_t k = 0; k < splits.size(); ++k) {
    eo.save_dir = !folder || f.no_renders ? "" : join_path(join_path(folder->path(), "renders"), names[k]);
    const SplitMetrics m = evaluate_split(model, splits[k], names[k], eo, progress);
    char line[200];
    std::snprintf(line, sizeof line, "%-16s %5zu  %6.2f  %6.4f  %11s", names[k].c_str(), m.views, m.psnr, m.ssim, fixed(m.psnr_moving).c_str());
    in.out << line << (eo.lpips_onnx.empty() ? "" : "   " + fixed(m.lpips, 4)) << (eo.ls_gain ? "   " + fixed(m.psnr_ls_gain) : "")
           << (eo.affine_fit ? "   " + fixed(m.psnr_affine) : "") << "\n";
    metrics.push_back(m);
  }
  if (folder) {
    write_metrics_json(join_path(folder->path(), "metrics.json"), metrics);
    folder->commit();
  }
  if (!truth && !std::any_of(splits.begin(), splits.end(), [](const Dataset& d) { return d.has_masks(); }))
    in.out << "(moving-region PSNR needs --truth SCENE, the ground truth with its moving Gaussians, or foreground masks in seg/ beside the cameras)\n";
  return 0;
}

}  // namespace

Action declare_eval(CLI::App& app) {
  auto f = std::make_shared<EvalFlags>();
  add_text(app, "--model", f->model, "the model", "PATH")->required();
  add_text(app, "--images", f->images, "the images folder", "DIR")->required();
  add_list(app, "--cameras", f->cameras, "one camera file per split")->required();
  add_list(app, "--splits", f->splits, "the splits' names (default: the camera files' names)");
  add_text(app, "--truth", f->truth, "the ground-truth scene: its moving Gaussians mark the moving region", "PATH");
  add_text(app, "--lpips", f->lpips, "LPIPS network (ONNX)", "PATH");
  add_text(app, "--colour-correction", f->colour_correction, "a colour_correction.json from train --colour-correction", "PATH");
  add_flag(app, "--ls-gain", f->ls_gain, "also PSNR after a least-squares gain per image");
  add_flag(app, "--affine-fit", f->affine_fit, "also PSNR after a least-squares affine colour map per image and channel");
  add_text(app, "--out", f->out, "the folder for metrics.json and renders", "DIR");
  add_flag(app, "--no-renders", f->no_renders, "no renders in --out");
  add_number(app, "--view-stride", f->view_stride, "every k-th view of each split", at_least(1));
  add_dataset_flags(app, f->data, "--select-cameras");
  add_scene_flags(app, f->read);
  return bind(f, eval);
}

}  // namespace fillgs::cli
