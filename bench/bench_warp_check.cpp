// Does the consistency mask tell a refined view's right pixels from its wrong ones, and is
// it circular for the warp refiner? On a finished `fillgs bench` folder (synthetic scenes:
// the truth is known), every first-round patch of the chosen runs — rendered by the
// backbone, so the model that refined and weighed them is known — is refined twice: by the
// bench's own refiner (its stored output) and by the `warp` refiner (the reference
// photograph warped through the backbone's depth, run here). For every virtual view:
//  * truth: a pixel is right when its colour is within 0.1 RMS of the ground truth's;
//  * the mask: FillGS's consistency (the two adjacent training views, through the
//    backbone's depth); for `warp` the reference is one of them, and the warp and the mask
//    use the same depth: the circular case;
//  * the mask without the reference: the adjacent training views other than the
//    reference's camera only;
//  * the flow check (flow_consistency): dense optical flow between the refined view and its
//    reference, both ways — no depth, no model.
// Printed and written to OUT/warp_check.{md,csv}: per refiner, the share of right pixels,
// each check's ROC AUC for right pixels, the flow check's precision and recall, and how
// often the mask (≥ 0.5) and the flow check agree; OUT/warp_check.png shows one view.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "bench_common.hpp"
#include "cli/options.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/threads.hpp"
#include "fillgs/base/json_file.hpp"
#include "fillgs/io/dataset.hpp"
#include "fillgs/io/plot.hpp"
#include "fillgs/io/scene_io.hpp"
#include "fillgs/method/refine.hpp"
#include "fillgs/method/weights.hpp"
#include "fillgs/model/frame_grid.hpp"
#include "fillgs/render/raster.hpp"

using namespace fillgs;

namespace {

constexpr double kRightRms = 0.1;  // a refined pixel is right within this RMS of the truth

struct Tally {
  std::vector<uint8_t> right;
  std::vector<float> mask, mask_no_reference, flow;
  size_t views = 0;
};

struct ViewRow {
  std::string refiner, run, file;
  int seed = 0, frame = 0;
  double axis_degrees = 0, right = 0, mask_mean = 0, mask_no_reference_mean = 0, flow_share = 0;
};

double angle_between_axes(const Camera& a, const Camera& b) {
  const Vec3d za = a.R.row(2).transpose(), zb = b.R.row(2).transpose();
  return std::acos(std::clamp(za.dot(zb), -1.0, 1.0)) * 180.0 / kPi;
}

std::vector<float> as_rgb(const std::vector<float>& grey) {
  std::vector<float> rgb(grey.size() * 3);
  for (size_t p = 0; p < grey.size(); ++p) rgb[p * 3] = rgb[p * 3 + 1] = rgb[p * 3 + 2] = grey[p];
  return rgb;
}

double fraction(const std::vector<uint8_t>& m) {
  size_t n = 0;
  for (uint8_t x : m) n += x;
  return m.empty() ? 0.0 : double(n) / double(m.size());
}

}  // namespace

int bench_warp_check(const std::vector<std::string>& args) {
  const ThreadLimit two_threads(2);
  std::string bench_dir = "bench/results/comparison", out = "bench/results/warp_check", scene = "n3v", seeds_text = "1,2,3",
              runs_text = "fillgs,random.w-none";
  auto app = cli::make_parser("fillgs_bench warp-check",
                              "the consistency mask and an optical-flow check against the truth, for the bench's refiner and the warp refiner");
  cli::add_text(*app, "--bench", bench_dir, "a finished fillgs bench folder (synthetic scene)", "DIR");
  cli::add_text(*app, "--out", out, "the folder for warp_check.md, .csv and .png", "DIR");
  cli::add_text(*app, "--scene", scene, "the bench's scene", "NAME");
  cli::add_text(*app, "--seeds", seeds_text, "the bench's seeds", "A,B,..");
  cli::add_text(*app, "--runs", runs_text, "runs whose first-round patches are checked", "A,B,..");
  if (!cli::parse_flags(*app, args, std::cout)) return 0;
  const std::vector<std::string> seeds = cli::split_commas(seeds_text), runs = cli::split_commas(runs_text);
  const char* refiners[] = {"bench", "warp"};
  std::map<std::string, Tally> tally;
  std::vector<ViewRow> rows;
  std::vector<std::vector<float>> picture;
  std::vector<std::string> captions;
  int pic_w = 0, pic_h = 0;
  double pic_best = -1;
  std::string bench_refiner;
  for (const std::string& seed : seeds) {
    const std::string root = join_path(bench_dir, scene + "_s" + seed);
    const std::string scene_dir = join_path(root, "scene");
    if (!std::filesystem::exists(join_path(root, "backbone/model.ply")))
      throw_error(join_path(root, "backbone/model.ply"), ": missing (run fillgs bench --out ", bench_dir, " first)");
    const GaussianCloud truth = read_scene(join_path(scene_dir, "scene.ply"));
    const GaussianCloud backbone = read_scene(join_path(root, "backbone/model.ply"));
    const Dataset data = Dataset::load(scene_dir, join_path(scene_dir, "transforms_train.json"));
    std::vector<Camera> cameras;
    for (const TrainView& v : data.views()) cameras.push_back(v.camera);
    WeightContext ctx;
    ctx.model = &backbone;
    ctx.views = observed_views(cameras, data.frames());
    ctx.image = [&](size_t i) { return Image(cameras[i].width, cameras[i].height, 3, data.image(i)); };
    ctx.frames = data.frames();
    for (const std::string& run : runs) {
      const std::string work = join_path(join_path(join_path(root, "runs"), run), "work");
      const nlohmann::json result = read_json_file(join_path(join_path(join_path(root, "runs"), run), "result.json"));
      const std::string used = result.value("support", std::string("?"));
      if (bench_refiner.empty()) bench_refiner = used;
      if (used != bench_refiner) throw_error(join_path(root, "runs/" + run), ": refined by '", used, "', the others by '", bench_refiner, "'");
      std::vector<std::string> patches;
      for (const auto& e : std::filesystem::directory_iterator(join_path(work, "patches")))
        if (e.path().filename().string().rfind("r0_", 0) == 0) patches.push_back(e.path().filename().string());
      std::sort(patches.begin(), patches.end());
      if (patches.empty()) throw_error(join_path(work, "patches"), ": no first-round patch (r0_*)");
      ReferenceOptions ro;
      auto warp = make_warp_refiner(ro);
      warp->begin_round(backbone, Vec3f::Zero());
      // The warp refiner's images, kept only while they are measured.
      const std::string warp_root = join_path(join_path(out, "work"), run);
      for (const std::string& name : patches) {
        const std::string in = join_path(join_path(work, "patches"), name);
        const Patch patch = read_patch(in);
        warp->refine(in, join_path(warp_root, name), patch);
        for (const PatchImage& im : patch.images) {
          if (im.observed) continue;
          const Camera& cam = im.camera;
          const PatchImage& ref = patch_reference(patch, im.frame);
          const Image reference = read_rgb_image(join_path(in, ref.file), ref.camera.width, ref.camera.height);
          const std::vector<float> t = render(frame_at(truth, cam.time), cam).rgb;
          // The training views other than the reference's camera.
          WeightContext others = ctx;
          others.views.clear();
          std::vector<size_t> kept;
          for (size_t v = 0; v < ctx.views.size(); ++v)
            if ((ctx.views[v].camera.centre() - ref.camera.centre()).norm() > 1e-6) kept.push_back(v), others.views.push_back(ctx.views[v]);
          others.image = [&](size_t i) { return ctx.image(kept[i]); };
          for (const char* which : refiners) {
            const std::string dir = std::string(which) == "warp" ? join_path(warp_root, name) : join_path(join_path(work, "refined"), name);
            const Image refined = read_rgb_image(join_path(dir, im.file), cam.width, cam.height);
            const size_t P = size_t(cam.width) * cam.height;
            std::vector<uint8_t> right(P);
            for (size_t p = 0; p < P; ++p) {
              double e = 0;
              for (int c = 0; c < 3; ++c) e += std::pow(refined.pixels[p * 3 + size_t(c)] - t[p * 3 + size_t(c)], 2.0);
              right[p] = std::sqrt(e / 3.0) <= kRightRms;
            }
            const ViewWeights all = compute_weights(ctx, refined, cam, Weighting::NoCovisibility, MaskOptions{});
            const std::vector<float> no_ref =
                others.views.empty() ? std::vector<float>(P, 0.0f)
                                     : compute_weights(others, refined, cam, Weighting::NoCovisibility, MaskOptions{}).consistency;
            const std::vector<uint8_t> flow = flow_consistency(refined, reference);
            Tally& tl = tally[which];
            tl.right.insert(tl.right.end(), right.begin(), right.end());
            tl.mask.insert(tl.mask.end(), all.consistency.begin(), all.consistency.end());
            tl.mask_no_reference.insert(tl.mask_no_reference.end(), no_ref.begin(), no_ref.end());
            tl.flow.insert(tl.flow.end(), flow.begin(), flow.end());
            ++tl.views;
            ViewRow r;
            r.refiner = which == std::string("bench") ? bench_refiner : which;
            r.run = run, r.file = name + "/" + im.file, r.seed = std::stoi(seed), r.frame = im.frame;
            r.axis_degrees = angle_between_axes(cam, ref.camera);
            r.right = fraction(right);
            for (size_t p = 0; p < P; ++p) r.mask_mean += all.consistency[p], r.mask_no_reference_mean += no_ref[p];
            r.mask_mean /= double(P), r.mask_no_reference_mean /= double(P);
            r.flow_share = fraction(flow);
            rows.push_back(r);
            // The picture: the warp refiner's view with the most wrong pixels the reference-including mask still trusts.
            if (std::string(which) == "warp") {
              double trusted_wrong = 0;
              for (size_t p = 0; p < P; ++p) trusted_wrong += !right[p] && all.consistency[p] >= 0.5f;
              trusted_wrong /= double(P);
              if (trusted_wrong > pic_best) {
                pic_best = trusted_wrong, pic_w = cam.width, pic_h = cam.height;
                const Image stored = read_rgb_image(join_path(join_path(join_path(work, "refined"), name), im.file), cam.width, cam.height);
                std::vector<float> right_f(P), flow_f(P);
                for (size_t p = 0; p < P; ++p) right_f[p] = right[p], flow_f[p] = flow[p];
                picture = {t, reference.pixels, stored.pixels, refined.pixels, as_rgb(right_f), as_rgb(all.consistency), as_rgb(no_ref), as_rgb(flow_f)};
                captions = {"truth", "reference", bench_refiner, "warp", "warp right", "mask", "mask w/o ref", "flow check"};
              }
            }
          }
        }
        std::filesystem::remove_all(join_path(warp_root, name));
      }
    }
  }
  std::filesystem::remove_all(join_path(out, "work"));
  // The tables.
  std::ostringstream md;
  md << "# Consistency checks against the truth\n\n"
     << "First-round virtual views of the runs " << runs_text << " of " << bench_dir << " (" << scene << ", seeds " << seeds_text
     << "), each refined by the bench's refiner (" << bench_refiner << ") and by the warp refiner, the backbone's depth. "
     << "Right: within " << kRightRms << " RMS of the truth. AUC: how well each check ranks right pixels above wrong ones (0.5 = chance). "
     << "Mask: FillGS's consistency with the two adjacent training views (the reference among them); without the reference: with the "
        "other training views only; flow: optical flow to the reference and back (no depth, no model).\n\n"
     << "| refiner | views | right | AUC mask | AUC mask w/o reference | AUC flow | flow precision | flow recall | mask ≥ 0.5 and flow agree |\n"
     << "|---|---|---|---|---|---|---|---|---|\n";
  char buf[512];
  for (const char* which : refiners) {
    const Tally& tl = tally[which];
    if (tl.right.empty()) continue;
    size_t pass = 0, pass_right = 0, right = 0, agree = 0;
    for (size_t p = 0; p < tl.right.size(); ++p) {
      right += tl.right[p];
      pass += tl.flow[p] > 0.5f;
      pass_right += tl.flow[p] > 0.5f && tl.right[p];
      agree += (tl.mask[p] >= 0.5f) == (tl.flow[p] > 0.5f);
    }
    const double n = double(tl.right.size());
    std::snprintf(buf, sizeof buf, "| %s | %zu | %.1f%% | %.3f | %.3f | %.3f | %.1f%% | %.1f%% | %.1f%% |\n",
                  std::string(which) == "bench" ? bench_refiner.c_str() : which, tl.views, 100 * double(right) / n,
                  roc_auc(tl.mask, tl.right), roc_auc(tl.mask_no_reference, tl.right), roc_auc(tl.flow, tl.right),
                  pass ? 100 * double(pass_right) / double(pass) : 0.0, right ? 100 * double(pass_right) / double(right) : 0.0,
                  100 * double(agree) / n);
    md << buf;
  }
  md << "\n![one view](warp_check.png)\n\nThe warp refiner's view whose mask trusts the most wrong pixels: truth, reference, the bench's refiner, "
        "the warp refiner, its right pixels (white), the mask, the mask without the reference, the flow check.\n";
  make_directories(out);
  write_file_atomically(join_path(out, "warp_check.md"), md.str());
  std::ostringstream csv;
  csv << "refiner,seed,run,file,frame,axis_degrees,right,mask_mean,mask_no_reference_mean,flow_share\n";
  for (const ViewRow& r : rows) {
    std::snprintf(buf, sizeof buf, "%s,%d,%s,%s,%d,%.3f,%.4f,%.4f,%.4f,%.4f\n", r.refiner.c_str(), r.seed, r.run.c_str(), r.file.c_str(), r.frame,
                  r.axis_degrees, r.right, r.mask_mean, r.mask_no_reference_mean, r.flow_share);
    csv << buf;
  }
  write_file_atomically(join_path(out, "warp_check.csv"), csv.str());
  if (!picture.empty()) write_image_grid_png(join_path(out, "warp_check.png"), picture, pic_w, pic_h, captions, 4, 2);
  std::cout << md.str();
  return 0;
}
