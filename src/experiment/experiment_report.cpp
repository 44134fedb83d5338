// The benchmark's reports (experiment.hpp): its tables, charts and pages, the refiner's
// calibration, the paired statistics, and the run report.
#include "fillgs/experiment/experiment.hpp"
#include "experiment/experiment_text.hpp"
#include "fillgs/method/refiners.hpp"
#include "fillgs/method/strategies.hpp"
#include "fillgs/io/camera_io.hpp"
#include "fillgs/base/json_file.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <nlohmann/json.hpp>
#include <ostream>
#include <set>
#include <sstream>

#include "fillgs/base/error.hpp"
#include "fillgs/base/timing.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/experiment/identity.hpp"
#include "fillgs/io/html_report.hpp"
#include "fillgs/base/limits.hpp"
#include "fillgs/io/plot.hpp"
#include "fillgs/render/raster.hpp"
#include "fillgs/io/scene_io.hpp"

namespace fs = std::filesystem;

namespace fillgs {

namespace {
using detail::csv_cells;
using detail::fmt;
using detail::Moments;
}  // namespace

void write_refined_view_records(const std::string& path, const std::vector<RefinedViewRecord>& records) {
  std::ostringstream csv;
  csv.precision(7);
  csv << "file,frame,parallax_degrees,axis_degrees,baseline,support,confidence,psnr_refined,psnr_render,psnr_seen\n";
  for (const RefinedViewRecord& r : records)
    csv << r.file << "," << r.frame << "," << r.parallax_degrees << "," << r.axis_degrees << "," << r.baseline << "," << r.support << ","
        << r.confidence << "," << r.psnr_refined << "," << r.psnr_render << "," << r.psnr_seen << "\n";
  write_file_atomically(path, csv.str());
}

std::vector<RefinedViewRecord> read_refined_view_records(const std::string& path) {
  std::istringstream in(read_file(path));
  std::string line;
  std::getline(in, line);
  std::vector<RefinedViewRecord> out;
  for (size_t row = 2; std::getline(in, line); ++row) {
    if (line.empty()) continue;
    const std::vector<std::string> f = csv_cells(line);
    if (f.size() != 10) throw_error(path, ": line ", row, " has ", f.size(), " columns, expected 10");
    double v[9];
    for (size_t k = 1; k < 10; ++k) {
      if (f[k] == "nan" || f[k] == "-nan") v[k - 1] = std::nan("");
      else if (!parse_number(f[k], &v[k - 1])) throw_error(path, ": line ", row, " column ", k + 1, ": '", f[k], "' is not a number");
    }
    RefinedViewRecord r;
    r.file = f[0], r.frame = int(v[0]), r.parallax_degrees = v[1], r.axis_degrees = v[2], r.baseline = v[3], r.support = v[4];
    r.confidence = v[5], r.psnr_refined = v[6], r.psnr_render = v[7], r.psnr_seen = v[8];
    out.push_back(r);
  }
  return out;
}

void write_refiner_calibration(const std::string& path, const std::vector<std::pair<std::string, std::vector<RefinedViewRecord>>>& runs,
                               const std::string& title) {
  constexpr double kBin = 5.0;
  std::vector<ScatterSeries> series;
  std::map<int, std::array<Moments, 4>> bins;  // bin -> refined where the reference saw, whole refined image, render, support
  for (const auto& [label, records] : runs) {
    ScatterSeries pts;
    pts.name = "where the reference saw, " + label;
    pts.joined = false;
    for (const RefinedViewRecord& r : records) {
      if (!std::isfinite(r.psnr_refined)) continue;
      std::array<Moments, 4>& b = bins[int(r.parallax_degrees / kBin)];
      if (std::isfinite(r.psnr_seen)) {
        pts.x.push_back(r.parallax_degrees), pts.y.push_back(r.psnr_seen);
        b[0].add(std::min(r.psnr_seen, 60.0));  // an exact match (150 dB) would swamp a mean
      }
      b[1].add(r.psnr_refined);
      if (std::isfinite(r.psnr_render)) b[2].add(r.psnr_render);
      b[3].add(r.support);
    }
    if (!pts.x.empty()) series.push_back(std::move(pts));
  }
  if (bins.empty()) return;
  ScatterSeries seen_mean{"where the reference saw, mean per 5 degrees", {}, {}, {}, true},
      whole_mean{"whole image, mean per 5 degrees", {}, {}, {}, true}, render_mean{"the render it was given, mean per 5 degrees", {}, {}, {}, true};
  std::ostringstream md;
  md << "| parallax to the reference (degrees) | views | refined PSNR where the reference saw (dB) | refined PSNR, whole image (dB) | "
        "render given, whole image (dB) | share the reference saw |\n|---|---|---|---|---|---|\n";
  for (const auto& [bin, m] : bins) {
    const double centre = (bin + 0.5) * kBin;
    if (m[0].n) seen_mean.x.push_back(centre), seen_mean.y.push_back(m[0].mean());
    whole_mean.x.push_back(centre), whole_mean.y.push_back(m[1].mean());
    if (m[2].n) render_mean.x.push_back(centre), render_mean.y.push_back(m[2].mean());
    md << "| " << fmt(bin * kBin, 0) << "–" << fmt((bin + 1) * kBin, 0) << " | " << m[1].n << " | "
       << (m[0].n ? fmt(m[0].mean(), 2) + " ± " + fmt(m[0].sd(), 2) : "–") << " | " << fmt(m[1].mean(), 2) << " ± " << fmt(m[1].sd(), 2) << " | "
       << (m[2].n ? fmt(m[2].mean(), 2) : "–") << " | " << fmt(100 * m[3].mean(), 1) << "% |\n";
  }
  for (ScatterSeries* s : {&seen_mean, &whole_mean, &render_mean})
    if (!s->x.empty()) series.push_back(*s);
  write_scatter_png(path + ".png", series, {title, "parallax angle to the reference view (degrees, median over the view)", "PSNR against the truth (dB)"}, false);
  write_file_atomically(path + ".md", md.str());
}

double student_t_975(int df) {
  if (df < 1) throw_error("Student's t needs at least 1 degree of freedom, not ", df);
  // P(|T| <= t) for integer df (Abramowitz and Stegun 26.7.3-4), with theta = atan(t / sqrt(df)).
  auto central = [df](double t) {
    const double theta = std::atan(t / std::sqrt(double(df))), s = std::sin(theta), c2 = std::cos(theta) * std::cos(theta);
    double term = 1.0, sum = 1.0;
    if (df % 2 == 0) {
      for (int k = 2; k <= df - 2; k += 2) term *= c2 * double(k - 1) / double(k), sum += term;
      return s * sum;
    }
    if (df == 1) return 2.0 * theta / kPi;
    for (int k = 3; k <= df - 2; k += 2) term *= c2 * double(k - 1) / double(k), sum += term;
    return 2.0 / kPi * (theta + s * std::cos(theta) * sum);
  };
  double lo = 0.0, hi = 1000.0;  // t(0.975, 1) = 12.7
  for (int i = 0; i < 200 && hi - lo > 1e-12; ++i) {
    const double mid = 0.5 * (lo + hi);
    (central(mid) < 0.95 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

int seeds_for_half_width(double sd, double half_width) {
  if (!std::isfinite(sd) || !(half_width > 0)) return 0;
  // t(0.975, df) > 1.96 for every df, so no n below (1.96 sd / half-width)² can do.
  const double lower = std::ceil(std::pow(1.959963 * sd / half_width, 2));
  if (lower > 10000) return 0;
  for (int n = std::max(2, int(lower)); n <= 10000; ++n)
    if (student_t_975(n - 1) * sd / std::sqrt(double(n)) <= half_width) return n;
  return 0;
}

std::vector<PairedDifference> paired_differences(const std::vector<RunResult>& results, const std::string& reference) {
  auto values = [](const RunResult& r) {
    return std::array<double, 4>{r.interpolation.psnr, r.interpolation.psnr_moving, r.extrapolation.psnr, r.extrapolation.psnr_moving};
  };
  std::vector<PairedDifference> out;
  std::vector<std::array<Moments, 4>> moments;  // per entry of out
  // Indexes, so that the report is linear in its rows (a merge of 100,000 rows scanned them
  // all for each row): runs by (scene, seed, id), ids run per scene, out's rows by (scene, id).
  auto key = [](const std::string& variant, const std::string& id, uint64_t seed) { return variant + '\x1f' + id + '\x1f' + std::to_string(seed); };
  std::unordered_map<std::string, size_t> run_at, out_at;
  std::unordered_set<std::string> ran;
  for (size_t i = 0; i < results.size(); ++i) {
    run_at.emplace(key(results[i].variant, results[i].id, results[i].seed), i);
    ran.insert(key(results[i].variant, results[i].id, 0));
  }
  for (const RunResult& r : results) {
    if (r.id == "backbone") continue;
    // Each run against the reference of its own oracle: "x@full" against "fillgs@full", the
    // clean-oracle "x.clean" against "fillgs.clean".
    const size_t at = r.id.find('@');
    const std::string support = at == std::string::npos ? "" : r.id.substr(at);
    const std::string base = r.id.substr(0, at);
    const bool clean = base.size() > 6 && base.compare(base.size() - 6, 6, ".clean") == 0;
    auto find = [&](const std::string& id) {
      const auto at = run_at.find(key(r.variant, id, r.seed));
      return at == run_at.end() ? results.end() : results.begin() + ptrdiff_t(at->second);
    };
    // "random.w-none" against "fillgs.w-none" where it ran: one weighting, only the selection differs.
    const size_t w = base.find(".w-");
    const std::string same_weighting = w == std::string::npos || base.substr(0, w) == reference ? "" : reference + base.substr(w) + support;
    std::string ref_id = reference + (clean ? ".clean" : "") + support;
    if (!same_weighting.empty() && ran.count(key(r.variant, same_weighting, 0)))
      ref_id = same_weighting;
    if (r.id == ref_id) continue;
    const auto ref = find(ref_id);
    if (ref == results.end()) continue;
    const auto [slot, fresh] = out_at.emplace(key(r.variant, r.id, 0), out.size());
    if (fresh) {
      out.push_back({r.variant, r.id, r.group});
      moments.emplace_back();
    }
    const auto it = out.begin() + ptrdiff_t(slot->second);
    const std::array<double, 4> a = values(*ref), b = values(r);
    std::array<Moments, 4>& m = moments[size_t(it - out.begin())];
    for (size_t j = 0; j < 4; ++j) m[j].add(a[j] - b[j]);
  }
  for (size_t k = 0; k < out.size(); ++k) {
    out[k].seeds = moments[k][0].n;
    const int n = out[k].seeds;
    const double t = n > 1 ? student_t_975(n - 1) / std::sqrt(double(n)) : std::numeric_limits<double>::quiet_NaN();
    for (size_t j = 0; j < 4; ++j) out[k].mean[j] = moments[k][j].mean(), out[k].sd[j] = moments[k][j].sd(), out[k].half_width[j] = t * out[k].sd[j];
  }
  return out;
}

namespace {
/// "negative.w-none", "fillgs.w-none@oracle": a strategy's views with no weights.
bool unweighted_strategy_row(const std::string& id) {
  const std::string base = id.substr(0, id.find('@'));
  for (const StrategyRow* r : strategy_table().rows())
    if (base == r->name + ".w-none") return true;
  return false;
}
}  // namespace

void write_bench_report(const std::string& root, const std::vector<RunResult>& results) {
  // CSV: every run.
  std::ostringstream csv;
  csv << kResultsCsvHeader << "\n";
  for (const RunResult& r : results)
    csv << r.variant << "," << r.seed << "," << r.id << "," << to_string(r.group) << "," << r.support << "," << r.interpolation.psnr << "," << r.interpolation.ssim
        << "," << r.interpolation.psnr_moving << "," << r.extrapolation.psnr << "," << r.extrapolation.ssim << "," << r.extrapolation.psnr_moving
        << "," << r.train.psnr << "," << r.trajectories << "," << r.views_added << "," << r.mean_weight << "," << r.support_share << ","
        << r.refine_failures << "," << r.seconds_select << "," << r.seconds_refine << "," << r.seconds_weights << "," << r.seconds_train << ","
        << r.seconds_eval << "," << r.seconds_total << "\n";
  write_file_atomically(join_path(root, "results.csv"), csv.str());

  // Mean and standard deviation over seeds, per scene and configuration, in first-seen order.
  constexpr int kValues = 10;  // ip is im ep es em tp weight trajectories support
  struct Mean {
    std::string id, variant, support;
    ConfigGroup group = ConfigGroup::Control;
    int n = 0;
    Moments v[kValues];
    double t[5] = {};
    double mean(int k) const { return v[k].mean(); }
    double sd(int k) const { return v[k].sd(); }
  };
  std::vector<Mean> means;
  std::unordered_map<std::string, size_t> mean_at;  // (scene, id) -> row of means: linear in the runs
  for (const RunResult& r : results) {
    const auto [slot, fresh] = mean_at.emplace(r.variant + '\x1f' + r.id, means.size());
    if (fresh) {
      means.emplace_back();
      means.back().id = r.id, means.back().group = r.group, means.back().variant = r.variant, means.back().support = r.support;
    }
    const auto it = means.begin() + ptrdiff_t(slot->second);
    const double x[kValues] = {r.interpolation.psnr, r.interpolation.ssim, r.interpolation.psnr_moving, r.extrapolation.psnr,
                               r.extrapolation.ssim,  r.extrapolation.psnr_moving, r.train.psnr, r.mean_weight, double(r.trajectories),
                               r.support_share};
    for (int k = 0; k < kValues; ++k) it->v[k].add(x[k]);
    const double sec[5] = {r.seconds_select, r.seconds_refine, r.seconds_weights, r.seconds_train, r.seconds_eval};
    for (int k = 0; k < 5; ++k) it->t[k] += sec[k];
    it->n += 1;
  }
  for (Mean& m : means)
    for (double& x : m.t) x /= m.n;
  auto cell = [](const Mean& m, int k, int digits) {
    std::string c = fmt(m.mean(k), digits);
    if (m.n > 1 && std::isfinite(m.mean(k))) c += " ± " + fmt(m.sd(k), digits);
    return c;
  };
  std::set<std::string> scenes;
  for (const RunResult& r : results) scenes.insert(r.variant + " seed " + std::to_string(r.seed));
  std::ostringstream md;
  md << "# fillgs bench\n\nMean ± standard deviation over seeds, per scene; " << scenes.size() << " scene run(s):";
  for (const std::string& s : scenes) md << " " << s << ";";
  md << "\nPSNR in dB. \"moving\": PSNR over the pixels of the moving objects (ground truth). Train: PSNR on the training cameras. "
        "Refiner: \"reference\" is conditioned on the start view's own image at each frame (calibrated; bench/results/README.md), "
        "\"oracle\" restores the truth wherever any training camera saw it, \"oracle-full\" everywhere. "
        "\"supported\": share of the refined pixels the refiner's observations support.\n\n";
  const std::pair<ConfigGroup, const char*> groups[] = {{ConfigGroup::Control, "Without generated views"},
                                                      {ConfigGroup::Upper, "Upper bounds"},
                                                      {ConfigGroup::Calibration, "Refiner calibration (random views, no weights)"},
                                                      {ConfigGroup::Strategy, "Viewpoint selection strategies (Table 1 of the paper)"},
                                                      {ConfigGroup::Ablation, "FillGS selection ablations (Table 3 of the paper)"},
                                                      {ConfigGroup::Selection, "Other strategies with FillGS's fine-tuning and weights (Table 3 of the paper)"},
                                                      {ConfigGroup::Weighting, "Fine-tuning weights (Table 4 of the paper)"},
                                                      {ConfigGroup::Budget, "Trajectory budget per round"},
                                                      {ConfigGroup::Refiner, "Clean refiner (no injected artifacts)"},
                                                      {ConfigGroup::Unweighted, "Table 1 with one weighting: every strategy's views unweighted (only the selection differs)"}};
  auto in_group = [](const Mean& m, ConfigGroup g) {
    return m.group == g || (g == ConfigGroup::Control && m.id == "backbone") || (g == ConfigGroup::Unweighted && unweighted_strategy_row(m.id));
  };
  for (const auto& g : groups) {
    if (std::none_of(means.begin(), means.end(), [&](const Mean& m) { return in_group(m, g.first); })) continue;
    md << "## " << g.second << "\n\n| Scene | Method | refiner | Interp PSNR | SSIM | moving PSNR | Extrap PSNR | SSIM | moving PSNR | Train PSNR | weight | supported | runs |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const Mean& m : means) {
      if (!in_group(m, g.first)) continue;
      md << "| " << m.variant << " | " << m.id << " | " << (m.support.empty() ? "–" : m.support) << " | " << cell(m, 0, 2) << " | " << cell(m, 1, 3)
         << " | " << cell(m, 2, 2) << " | " << cell(m, 3, 2) << " | " << cell(m, 4, 3) << " | " << cell(m, 5, 2) << " | " << cell(m, 6, 2) << " | "
         << fmt(m.mean(7), 3) << " | " << (m.support.empty() ? "–" : fmt(100 * m.mean(9), 1) + "%") << " | " << m.n << " |\n";
    }
    md << "\n";
  }
  const std::vector<PairedDifference> paired = paired_differences(results);
  bool paired_chart = false;
  if (!paired.empty()) {
    md << "## FillGS − each method, paired by seed\n\nPer seed, FillGS's PSNR minus the method's (dB; positive: FillGS ahead): the mean "
          "over the seeds both ran, ± the standard deviation, and the 95 % confidence interval of the mean (t over the paired seeds); "
          "**separated** only where the interval excludes 0. A strategy's unweighted row (`x.w-none`) is paired with FillGS's unweighted "
          "row, every other row with `fillgs`. Ablation and weighting rows read as the paper's Tables 3 and 4: what the component "
          "is worth. \"Seeds for ±0.5\": where an interval is wider than ±0.5 dB, the paired seeds its measured SD would need "
          "for ±0.5 dB (interpolation / extrapolation; \"met\" where it already is).\n\n"
          "| Scene | Method | group | Interp ΔPSNR | 95 % CI | Extrap ΔPSNR | 95 % CI | moving Δ interp / extrap | seeds | seeds for ±0.5 |\n"
          "|---|---|---|---|---|---|---|---|---|---|\n";
    auto interval = [](const PairedDifference& d, int j) {
      if (d.seeds < 2) return std::string("–");
      const std::string iv = "[" + fmt(d.mean[j] - d.half_width[j], 2) + ", " + fmt(d.mean[j] + d.half_width[j], 2) + "]";
      return d.separated(j) ? "**" + iv + "**" : iv;
    };
    auto seeds_needed = [](const PairedDifference& d, int j) {
      if (d.seeds < 2) return std::string("–");
      if (d.half_width[j] <= 0.5) return std::string("met");
      const int n = seeds_for_half_width(d.sd[j], 0.5);
      return n > 0 ? std::to_string(n) : std::string("> 10,000");
    };
    for (const PairedDifference& d : paired) {
      md << "| " << d.variant << " | " << d.id << " | " << to_string(d.group);
      for (int j : {0, 2}) md << " | " << fmt(d.mean[j], 2) << (d.seeds > 1 ? " ± " + fmt(d.sd[j], 2) : "") << " | " << interval(d, j);
      md << " | " << fmt(d.mean[1], 2) << " / " << fmt(d.mean[3], 2) << " | " << d.seeds << " | " << seeds_needed(d, 0) << " / " << seeds_needed(d, 2)
         << " |\n";
    }
    md << "\n";
    // Table 1's intervals as a picture (the first scene): each strategy under both protocols
    // (its own weights; one weighting) and the control.
    std::vector<std::string> rows;
    IntervalSeries si{"interpolation", {}, {}, {}}, se{"extrapolation", {}, {}, {}};
    for (const PairedDifference& d : paired) {
      if (d.variant != paired.front().variant || d.seeds < 2) continue;
      // FillGS's own rows (its weights against none) belong to Table 4, not here.
      if (d.id.rfind("fillgs", 0) == 0 || !(d.group == ConfigGroup::Strategy || d.id == "no-refinement" || unweighted_strategy_row(d.id))) continue;
      rows.push_back(d.id);
      for (auto [series, j] : {std::pair<IntervalSeries*, int>{&si, 0}, {&se, 2}}) {
        series->estimate.push_back(d.mean[j]);
        series->low.push_back(d.mean[j] - d.half_width[j]);
        series->high.push_back(d.mean[j] + d.half_width[j]);
      }
    }
    if (!rows.empty()) {
      write_interval_chart_png(join_path(root, "paired_table1.png"), rows, {si, se},
                               {"FillGS minus each (" + paired.front().variant + "): mean and 95 % interval over paired seeds; filled: excludes 0",
                                "PSNR difference (dB; x.w-none rows: FillGS's unweighted row minus x's)", ""});
      paired_chart = true;
    }
  }
  md << "## Seconds per phase (mean per run)\n\n| Scene | Method | select | refine | weights | train | eval |\n|---|---|---|---|---|---|---|\n";
  for (const Mean& m : means)
    if (m.id != "backbone")
      md << "| " << m.variant << " | " << m.id << " | " << fmt(m.t[0], 1) << " | " << fmt(m.t[1], 1) << " | " << fmt(m.t[2], 1) << " | " << fmt(m.t[3], 1) << " | "
         << fmt(m.t[4], 1) << " |\n";

  // Plots of the first scene: strategies with the first support mode, the control, the upper bounds.
  const std::string plotted = means.empty() ? "" : means.front().variant;
  std::vector<std::string> names;
  std::vector<double> interp, extrap;
  for (const Mean& m : means)
    if (m.variant == plotted && m.id.find('@') == std::string::npos &&
        (m.group == ConfigGroup::Strategy || m.group == ConfigGroup::Control || m.group == ConfigGroup::Upper || m.id == "backbone"))
      names.push_back(m.id), interp.push_back(m.mean(0)), extrap.push_back(m.mean(3));
  if (!names.empty()) {
    write_bar_chart_png(join_path(root, "psnr_interpolation.png"), names, interp, {"interpolation PSNR per strategy (" + plotted + ")", "", "PSNR (dB)"});
    write_bar_chart_png(join_path(root, "psnr_extrapolation.png"), names, extrap, {"extrapolation PSNR per strategy (" + plotted + ")", "", "PSNR (dB)"});
  }
  ScatterSeries bi{"interpolation", {}, {}, {}}, be{"extrapolation", {}, {}, {}};
  for (const Mean& m : means)
    if (m.variant == plotted && m.id.find('@') == std::string::npos && (m.group == ConfigGroup::Budget || m.id == method_strategy().name)) {
      bi.x.push_back(m.mean(8)), bi.y.push_back(m.mean(0));
      be.x.push_back(m.mean(8)), be.y.push_back(m.mean(3));
    }
  if (bi.x.size() >= 2)
    write_scatter_png(join_path(root, "budget.png"), {bi, be}, {"FillGS: PSNR against trajectories (3 rounds)", "trajectories in all", "PSNR (dB)"},
                      false);
  const char* phases[] = {"select", "refine", "weights", "train", "eval"};
  std::vector<double> t(5, 0.0);
  int runs = 0;
  for (const Mean& m : means)
    if (m.id != "backbone") {
      for (int k = 0; k < 5; ++k) t[size_t(k)] += m.t[k];
      ++runs;
    }
  if (runs) {
    for (double& x : t) x /= runs;
    write_bar_chart_png(join_path(root, "time_per_phase.png"), std::vector<std::string>(phases, phases + 5), t,
                        {"mean seconds per phase and run", "", "seconds"});
  }
  // Each strategy's gain over the control (same scene), per refiner: the chart the
  // comparison is read from.
  std::vector<std::string> figures = {"psnr_interpolation", "psnr_extrapolation", "budget", "time_per_phase"};
  if (paired_chart) figures.insert(figures.begin(), "paired_table1");
  {
    std::vector<std::string> gain_names;
    std::vector<double> gain_interp, gain_extrap;
    for (const Mean& m : means) {
      if (m.variant != plotted || m.group != ConfigGroup::Strategy) continue;
      const auto found = mean_at.find(m.variant + '\x1f' + "no-refinement");
      if (found == mean_at.end()) continue;
      const auto control = means.begin() + ptrdiff_t(found->second);
      gain_names.push_back(m.id);
      gain_interp.push_back(m.mean(0) - control->mean(0));
      gain_extrap.push_back(m.mean(3) - control->mean(3));
    }
    if (!gain_names.empty()) {
      write_bar_chart_png(join_path(root, "gain_interpolation.png"), gain_names, gain_interp,
                          {"interpolation: gain over the control per strategy and refiner (" + plotted + ")", "", "PSNR gain (dB)"});
      write_bar_chart_png(join_path(root, "gain_extrapolation.png"), gain_names, gain_extrap,
                          {"extrapolation: gain over the control per strategy and refiner (" + plotted + ")", "", "PSNR gain (dB)"});
      figures.insert(figures.begin(), {"gain_interpolation", "gain_extrapolation"});
    }
  }
  // The refiner's calibration: refined-vs-truth PSNR against the angle to the reference, over
  // the calibration runs this folder holds (one per refiner that records its views).
  if (fs::is_directory(root)) {
    std::map<std::string, std::vector<std::pair<std::string, std::vector<RefinedViewRecord>>>> by_id;
    std::vector<fs::path> scene_dirs;
    for (const auto& e : fs::directory_iterator(root))
      if (e.is_directory()) scene_dirs.push_back(e.path());
    std::sort(scene_dirs.begin(), scene_dirs.end());
    for (const fs::path& sc : scene_dirs) {
      if (!fs::is_directory(sc / "runs")) continue;
      std::vector<fs::path> runs;
      for (const auto& e : fs::directory_iterator(sc / "runs")) runs.push_back(e.path());
      std::sort(runs.begin(), runs.end());
      for (const fs::path& run : runs)
        if (run.filename().string().rfind("random.w-none", 0) == 0 && fs::exists(run / "refined_views.csv") && fs::exists(run / "result.json"))
          by_id[run.filename().string()].emplace_back(sc.filename().string(), read_refined_view_records((run / "refined_views.csv").string()));
    }
    for (const auto& [id, runs] : by_id) {
      const std::string name = "calibration" + id.substr(std::string("random.w-none").size());
      write_refiner_calibration(join_path(root, name), runs, "refiner calibration: " + id + " (random views)");
      if (fs::exists(join_path(root, name + ".md"))) {
        md << "\n## Refiner calibration (" << id << ")\n\nRefined-vs-truth PSNR of the random views against the parallax angle to "
              "their reference view, per 5° bin over every seed (the render it was given alongside).\n\n"
           << read_file(join_path(root, name + ".md")) << "\n";
        figures.push_back(name);
      }
    }
  }
  // The figures drawn above, named in the Markdown (and so embedded in the HTML page).
  md << "\n## Figures\n\nEach figure's numbers are in the CSV of its name, and `gnuplot NAME.gp` re-draws it.\n\n";
  for (const std::string& f : figures)
    if (fs::exists(join_path(root, f + ".png"))) md << "![" << f << "](" << f << ".png)\n\n";
  write_file_atomically(join_path(root, "results.md"), md.str());
  write_html_report(join_path(root, "results.md"), join_path(root, "results.html"));
}

void write_run_report(const std::string& dir, const RunReportInput& in) {
  const ExperimentOptions& o = in.scene->options;
  // Side-by-side pictures: ground truth | backbone | each fine-tuned model, at the moment of
  // each split where the moving content covers most of a view (a moving moment).
  std::vector<GaussianCloud> models = {in.scene->backbone};
  for (const std::string& id : in.run_ids) models.push_back(read_scene(join_path(join_path(join_path(in.scene->dir, "runs"), id), "model.ply")));
  std::vector<std::string> pictures;
  for (const auto* split : {in.scene->extrapolation.get(), in.scene->interpolation.get()}) {
    size_t best = 0, most = 0;
    for (size_t v = 0; v < split->views().size(); ++v) {
      const std::vector<unsigned char> m = moving_region(in.scene->synth.scene, split->views()[v].camera);
      const size_t n = size_t(std::count(m.begin(), m.end(), 1));
      if (n > most) most = n, best = v;
    }
    const TrainView& view = split->views()[best];
    std::vector<std::vector<float>> imgs = {split->image(best)};
    std::vector<std::string> caps = {"ground truth"};
    for (size_t m = 0; m < models.size(); ++m) {
      imgs.push_back(render(frame_at(models[m], view.camera.time), view.camera).rgb);
      caps.push_back(m == 0 ? "backbone" : in.run_ids[m - 1]);
    }
    const std::string file = "compare_" + view.rig + "_f" + std::to_string(view.frame) + ".png";
    write_side_by_side_png(join_path(dir, file), imgs, view.camera.width, view.camera.height, caps, 2);
    pictures.push_back(file);
  }
  // Report.
  std::ostringstream md;
  md << "# fillgs run\n\nScene: built-in synthetic (" << o.scene_name() << "), " << o.width << "x" << o.height << ", " << o.frames
     << " frames; backbone trained on " << in.scene->train->rigs().size() << " cameras (";
  for (size_t k = 0; k < in.scene->options.train_cameras.size(); ++k) md << (k ? ", " : "") << in.scene->options.train_cameras[k];
  md << ") for " << o.backbone_iterations << " iterations; each fine-tuning: " << in.finetune.iterations << " iterations, "
     << in.finetune.trajectories << " trajectories every " << in.finetune.select_every << " iterations, refiner `" << in.refiner << "` ("
     << refiner_kind(in.refiner).description << (refiner_kind(in.refiner).calibrated ? "; calibrated before any strategy ran with it, see the calibration below" : "")
     << ") with artifacts (strength " << in.artifact_strength << "). Baselines use ExploreGS weights (the paper's protocol); FillGS its own.\n\n";
  // The result as measured, in one sentence.
  auto find = [&](const std::string& id) -> const RunResult* {
    for (const RunResult& r : in.results)
      if (r.id == id) return &r;
    return nullptr;
  };
  const RunResult* ours = find("fillgs");
  const RunResult* control = find("no-refinement");
  const RunResult* other = nullptr;
  for (const std::string& id : in.run_ids)
    if (id != "fillgs" && id != "no-refinement") other = find(id);
  if (ours && control && other) {
    auto signed_db = [](double x) { return (x >= 0 ? "+" : "") + fmt(x) + " dB"; };
    md << "**Measured here:** FillGS " << fmt(ours->interpolation.psnr) << " / " << fmt(ours->extrapolation.psnr) << " dB (interpolation / "
       << "extrapolation), " << other->id << " " << fmt(other->interpolation.psnr) << " / " << fmt(other->extrapolation.psnr)
       << " dB, no generated views " << fmt(control->interpolation.psnr) << " / " << fmt(control->extrapolation.psnr) << " dB: FillGS "
       << signed_db(ours->interpolation.psnr - other->interpolation.psnr) << " / " << signed_db(ours->extrapolation.psnr - other->extrapolation.psnr)
       << " against " << other->id << ", " << signed_db(ours->interpolation.psnr - control->interpolation.psnr) << " / "
       << signed_db(ours->extrapolation.psnr - control->extrapolation.psnr)
       << " against the control. One seed; the benchmark's tables over three seeds are in bench/results/README.md.\n\n";
  }
  md << "| Method | Interp PSNR | SSIM | moving PSNR | Extrap PSNR | SSIM | moving PSNR | Train PSNR | seconds |\n|---|---|---|---|---|---|---|---|---|\n";
  for (const RunResult& r : in.results) {
    md << "| " << r.id << " | " << fmt(r.interpolation.psnr) << " | " << fmt(r.interpolation.ssim, 3) << " | " << fmt(r.interpolation.psnr_moving)
       << " | " << fmt(r.extrapolation.psnr) << " | " << fmt(r.extrapolation.ssim, 3) << " | " << fmt(r.extrapolation.psnr_moving) << " | "
       << fmt(r.train.psnr) << " | " << fmt(r.seconds_total, 0) << " |\n";
  }
  md << "\n## Renders\n\nGround truth, the backbone and each fine-tuned model at the view and moment of each split where the moving content "
        "covers most of the image.\n\n";
  for (const std::string& f : pictures) md << "![" << f << "](" << f << ")\n\n";
  for (const char* chart : {"psnr_interpolation", "psnr_extrapolation"})
    if (fs::exists(join_path(dir, std::string(chart) + ".png"))) md << "![" << chart << "](" << chart << ".png)\n\n";
  // What the refiner made of these runs' views against the truth.
  std::vector<std::pair<std::string, std::vector<RefinedViewRecord>>> records;
  for (const std::string& id : in.run_ids) {
    const std::string csv = join_path(join_path(join_path(in.scene->dir, "runs"), id), "refined_views.csv");
    if (fs::exists(csv)) records.emplace_back(id, read_refined_view_records(csv));
  }
  write_refiner_calibration(join_path(dir, "refiner"), records, "the refiner on this run's views");
  if (fs::exists(join_path(dir, "refiner.png")))
    md << "## The refiner\n\nEach refined view against the truth, by the parallax angle to the start view it was conditioned on (the "
          "benchmark's calibration on random views: bench/results/README.md, \"Calibrating the refiner\").\n\n![refiner](refiner.png)\n\n"
       << read_file(join_path(dir, "refiner.md")) << "\n";
  // The virtual views each strategy chose (top view), copied beside the report.
  md << "## Virtual views\n\n";
  for (const std::string& id : in.run_ids) {
    const std::string from = join_path(join_path(join_path(in.scene->dir, "runs"), id), "views.png"), file = "views_" + id + ".png";
    std::error_code ec;
    if (id != "no-refinement" && fs::exists(from, ec) && fs::copy_file(from, join_path(dir, file), fs::copy_options::overwrite_existing, ec))
      md << "![" << file << "](" << file << ")\n\n";
  }
  md << "## Command\n\n```\n" << in.command << "\n```\n\n";
  md << "Per-run folders (patches, refined views with their support, consistency mask, co-visibility and weight images): `"
     << join_path(in.scene->dir, "runs") << "`.\n";
  write_file_atomically(join_path(dir, "report.md"), md.str());
  write_html_report(join_path(dir, "report.md"), join_path(dir, "report.html"));
}

}  // namespace fillgs
