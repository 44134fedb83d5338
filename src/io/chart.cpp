// Charts through gnuplot (src/README.md, "Figures and reports"): every chart is three files side by side, NAME.csv
// (the numbers), NAME.gp (the gnuplot script that draws them: `cd DIR && gnuplot NAME.gp`
// re-makes the figure, edited or not) and NAME.png (pngcairo). fillgs writes the CSV and
// script, then gives the script to gnuplot on its standard input (started without a shell:
// base/process.hpp) with the output sent to a temporary file that is renamed into place, so
// a PNG is whole or absent. Without gnuplot (or when it fails) the
// CSV and script stay and one warning line says so: a missing figure never fails a run.
//
// gnuplot rather than PLplot: the script beside each figure lets users re-plot from the CSV
// with a tool they already have, without fillgs; it picks round ticks itself; pngcairo
// draws antialiased text; and it runs as a separate process, so a plotting failure cannot
// take a training run down with it.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <sstream>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/process.hpp"
#include "fillgs/io/plot.hpp"

namespace fillgs {

namespace {

namespace fs = std::filesystem;

/// A string as a gnuplot single-quoted literal ('' stands for ').
std::string quoted(const std::string& s) {
  std::string out = "'";
  for (char c : s) {
    if (c == '\'') out += "''";
    else if (c == '\n') out += ' ';
    else out += c;
  }
  return out + "'";
}

/// A CSV field: quoted when it holds a comma, quote or space.
std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\" ") == std::string::npos && !s.empty()) return s;
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

std::string number(double v) {
  if (!std::isfinite(v)) return "NaN";
  char b[40];
  std::snprintf(b, sizeof b, "%.9g", v);
  return b;
}

/// The value written on a bar: 2 decimals from 1 to 1000 (PSNR differences of 0.05 dB
/// matter), whole numbers above, 3 significant digits below 1.
std::string bar_value(double v) {
  char b[40];
  const double a = std::fabs(v);
  if (!std::isfinite(v)) return "";
  if (a >= 1000) std::snprintf(b, sizeof b, "%.0f", v);
  else if (a >= 1 || a == 0) std::snprintf(b, sizeof b, "%.2f", v);
  else std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

/// A tic label: 4 significant digits, no trailing zeros.
std::string compact(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.4g", v);
  return b;
}

std::string read_file_or_empty(const std::string& path) {
  try {
    return read_file(path);
  } catch (const Error&) {
    return {};
  }
}

std::string gnuplot_program() {
  const char* env = std::getenv("FILLGS_GNUPLOT");
  return env && *env ? env : "gnuplot";
}

/// The terminal and style every chart shares. Sizes are pixels; fonts are points.
std::string preamble(int width, int height) {
  std::ostringstream s;
  s << "set terminal pngcairo size " << width << "," << height << " noenhanced font 'DejaVu Sans,10'\n"
    << "set datafile separator ','\n"
    << "set border 3 lc rgb '#404040'\n"
    << "set tics nomirror\n"
    << "set grid ytics lc rgb '#dddddd' lt 1\n"
    << "set style fill solid 0.85 noborder\n";
  return s.str();
}

/// Writes NAME.csv and NAME.gp, then draws NAME.png by piping the script into gnuplot.
/// `script` names its data file as NAME.csv and writes to the output the caller set.
void draw(const std::string& png_path, const std::string& csv, const std::string& body, int width, int height) {
  const fs::path png(png_path);
  const std::string dir = png.parent_path().empty() ? "." : png.parent_path().string();
  const std::string stem_name = png.stem().string();
  const std::string csv_path = join_path(dir, stem_name + ".csv"), gp_path = join_path(dir, stem_name + ".gp");
  write_file_atomically(csv_path, csv);
  const std::string head = "# " + stem_name + ".png from " + stem_name + ".csv (written by fillgs); re-plot with: gnuplot " +
                           stem_name + ".gp\n" + preamble(width, height);
  write_file_atomically(gp_path, head + "set output " + quoted(stem_name + ".png") + "\n" + body);

  // gnuplot runs with an argument vector, not through a shell, and reads its script on
  // stdin: every path in it is a gnuplot string literal (quoted), never shell syntax.
  // The log is a locked temporary file: a run killed while gnuplot draws leaves it unlocked,
  // and the next command on the folder removes it (as it does the PNG's temporary file).
  const LockedTemporary log(join_path(dir, stem_name + ".gnuplot.log"));
  const std::string& log_path = log.path();
  std::string why;
  try {
    if (png_path.find('\n') != std::string::npos) throw_error(png_path, ": a line break in the path");
    // The PNG appears whole or not at all: gnuplot draws into write_atomically's temporary file.
    write_atomically(png_path, [&](const std::string& tmp) {
      ProcessOptions po;
      po.stdin_data = "cd " + quoted(fs::absolute(dir).string()) + "\n" + head + "set output " + quoted(fs::absolute(tmp).string()) + "\n" +
                      body + "set output\n";
      po.stderr_path = log_path;
      po.timeout_seconds = 120;
      const ProcessResult r = run_process({gnuplot_program()}, po);
      std::error_code ec;
      if (!r.started) why = r.error + "; Debian gnuplot-nox, which scripts/install-deps.sh installs";
      else if (r.timed_out) why = "gnuplot ran longer than 120 s";
      else if (r.status != 0) why = "gnuplot exited with status " + std::to_string(r.status);
      if (!why.empty() || !fs::exists(tmp, ec) || fs::file_size(tmp, ec) == 0) throw_error(png_path, ": gnuplot failed");
    });
  } catch (const Error& e) {
    const std::string log = read_file_or_empty(log_path);
    if (!log.empty()) why = log.substr(0, log.find('\n'));
    if (why.empty()) why = e.what();
    std::cerr << "warning: " << png_path << " not drawn (" << why << "); its data and script are in " << stem_name << ".csv and "
              << stem_name << ".gp\n";
  }
}

/// `set ytics ("a" 0, "b" 1, ...)` for named rows; nothing without names.
std::string ytic_names(const std::vector<std::string>& names) {
  if (names.empty()) return "";
  std::string t = "set ytics (";
  for (size_t r = 0; r < names.size(); ++r) t += (r ? ", " : "") + quoted(names[r]) + " " + std::to_string(r);
  return t + ")\n";
}

const char* const kSeriesColours[] = {"#3c78b4", "#e0872c", "#4aa04a", "#b44a4a"};

std::string title_lines(const PlotLabels& labels) {
  std::string s;
  if (!labels.title.empty()) s += "set title " + quoted(labels.title) + "\n";
  s += "set xlabel " + quoted(labels.x) + "\nset ylabel " + quoted(labels.y) + "\n";
  return s;
}

}  // namespace

void write_bar_chart_png(const std::string& path, const std::vector<std::string>& names, const std::vector<double>& values,
                         const PlotLabels& labels) {
  FILLGS_CHECK_EQ(names.size(), values.size());
  const size_t n = values.size();
  std::ostringstream csv;
  csv << "name,value,label\n";
  for (size_t i = 0; i < n; ++i) csv << csv_field(names[i]) << "," << number(values[i]) << "," << csv_field(bar_value(values[i])) << "\n";
  // Up to 24 bars carry their value and every name; beyond, every k-th name so they never
  // touch (names are rotated 45°, one per ~18 px).
  const int width = int(std::clamp<size_t>(160 + 44 * n, 640, 1400)), height = 480;
  const size_t every = std::max<size_t>(1, size_t(std::ceil(double(n) * 18.0 / (width - 160))));
  // Names go into the script as tic labels (gnuplot's CSV reading splits quoted commas).
  std::ostringstream tics;
  for (size_t i = 0; i < n; i += every) tics << (i ? ", " : "") << quoted(names[i]) << " " << i;
  std::ostringstream gp;
  gp << title_lines(labels) << "set key off\n"
     << "set xtics rotate by -45 left scale 0 (" << tics.str() << ")\n"
     << "set xrange [-0.6:" << number(double(n) - 0.4) << "]\n"
     << "set yrange [*<0:*]\nset offsets 0, 0, graph 0.08, 0\n"
     << "set boxwidth 0.7\n"
     << "plot '" << fs::path(path).stem().string() << ".csv' skip 1 using 0:2 with boxes lc rgb '#3c78b4'";
  if (n <= 24) gp << ", '' skip 1 using 0:2:3 with labels offset 0,0.7 font ',9'";
  gp << "\n";
  draw(path, csv.str(), gp.str(), width, height);
}

void write_interval_chart_png(const std::string& path, const std::vector<std::string>& rows, const std::vector<IntervalSeries>& series,
                              const PlotLabels& labels) {
  FILLGS_CHECK(!series.empty() && series.size() <= 4);
  const size_t n = rows.size();
  // CSV: one line per row and series: the series (its index in the legend), its y (the row,
  // offset by the series within it), the estimate, the interval, whether it excludes 0 (1)
  // or not (0), and the names.
  std::ostringstream csv;
  csv << "series,y,estimate,low,high,separated,row_name,series_name\n";
  double extent = 0.5;
  const double band = 0.5;  // of a row's height, shared by its series
  for (size_t k = 0; k < series.size(); ++k) {
    const IntervalSeries& s = series[k];
    FILLGS_CHECK(s.estimate.size() == n && s.low.size() == n && s.high.size() == n);
    const double offset = series.size() == 1 ? 0.0 : band * (double(k) / double(series.size() - 1) - 0.5);
    for (size_t r = 0; r < n; ++r) {
      if (!std::isfinite(s.estimate[r]) || !std::isfinite(s.low[r]) || !std::isfinite(s.high[r])) continue;
      extent = std::max({extent, std::fabs(s.low[r]), std::fabs(s.high[r])});
      const bool separated = s.low[r] > 0 || s.high[r] < 0;
      csv << k << "," << number(double(r) + offset) << "," << number(s.estimate[r]) << "," << number(s.low[r]) << "," << number(s.high[r]) << ","
          << (separated ? 1 : 0) << "," << csv_field(rows[r]) << "," << csv_field(s.name) << "\n";
    }
  }
  const std::string data = quoted(fs::path(path).stem().string() + ".csv");
  std::ostringstream gp;
  gp << title_lines(labels) << "set key outside right top vertical\nunset grid\nset grid xtics lc rgb '#dddddd' lt 1\n"
     << "set yrange [" << number(double(n) - 0.5) << ":-0.5]\nset ytics scale 0\n" << ytic_names(rows)
     << "set xrange [" << number(-1.1 * extent) << ":" << number(1.1 * extent) << "]\n"
     << "set arrow from 0, graph 0 to 0, graph 1 nohead dt 2 lc rgb '#404040'\n"
     << "plot ";
  // Each series takes its own lines of the CSV (column 1), so the CSV stays one table: a
  // filled point where the interval excludes 0 (column 6), an open one where it does not.
  for (size_t k = 0; k < series.size(); ++k)
    for (const bool separated : {true, false})
      gp << (k || !separated ? ", \\\n     " : "") << data << " skip 1 using ($1 == " << k << " && $6 " << (separated ? ">" : "<") << " 0.5 ? $3 : NaN):2:4:5 with xerrorbars pt "
         << (separated ? 7 : 6) << " ps 1.3 lw 2 lc rgb '" << kSeriesColours[k] << "' " << (separated ? "title " + quoted(series[k].name) : std::string("notitle"));
  gp << "\n";
  draw(path, csv.str(), gp.str(), 900, int(std::clamp<size_t>(140 + 34 * n, 300, 1200)));
}

namespace {

const char* const kPalette[] = {"#3c78b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#7f7f7f"};

struct Box {
  double x0, y0, x1, y1;
  double overlap(const Box& o) const {
    return std::max(0.0, std::min(x1, o.x1) - std::max(x0, o.x0)) * std::max(0.0, std::min(y1, o.y1) - std::max(y0, o.y0));
  }
};

}  // namespace

void write_scatter_png(const std::string& path, const std::vector<ScatterSeries>& series, const PlotLabels& labels, bool log_x) {
  // The plot area is fixed on the canvas (margins at screen fractions), so a point's pixel is
  // known here and point labels are placed where they cover no other label or point.
  const int width = 960, height = 600;
  const double left = 0.09, right = 0.74, bottom = 0.12, top = 0.90;
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  auto fx = [&](double x) { return log_x ? std::log10(std::max(x, 1e-300)) : x; };
  for (const auto& s : series) {
    FILLGS_CHECK_EQ(s.x.size(), s.y.size());
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i]) || (log_x && s.x[i] <= 0)) continue;
      x0 = std::min(x0, fx(s.x[i])), x1 = std::max(x1, fx(s.x[i]));
      y0 = std::min(y0, s.y[i]), y1 = std::max(y1, s.y[i]);
    }
  }
  if (!(x1 >= x0)) x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  if (!(x1 > x0)) x0 -= 0.5, x1 += 0.5;
  if (!(y1 > y0)) y0 -= 0.5, y1 += 0.5;
  const double px = 0.06 * (x1 - x0), py = 0.08 * (y1 - y0);
  x0 -= px, x1 += px, y0 -= py, y1 += py;
  auto pixel = [&](double x, double y) {
    return std::pair<double, double>((left + (right - left) * (fx(x) - x0) / (x1 - x0)) * width,
                                     (1 - (bottom + (top - bottom) * (y - y0) / (y1 - y0))) * height);
  };

  std::ostringstream csv, placed;
  csv << "series,x,y,label,label_x,label_y,series_name\n";  // series: its index in the legend
  std::vector<Box> taken;
  for (const auto& s : series)
    for (size_t i = 0; i < s.x.size(); ++i) {
      const auto [u, v] = pixel(s.x[i], s.y[i]);
      taken.push_back({u - 5, v - 5, u + 5, v + 5});
    }
  const double char_w = 6.6, text_h = 13;  // DejaVu Sans 9 pt in pngcairo, approximately
  for (size_t k = 0; k < series.size(); ++k) {
    const auto& s = series[k];
    // Points are joined in order of x.
    std::vector<size_t> order(s.x.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return s.x[a] < s.x[b]; });
    for (const size_t i : order) {
      std::string label = i < s.point_labels.size() ? s.point_labels[i] : std::string();
      double dx = 0, dy = 0;
      if (!label.empty()) {
        const auto [u, v] = pixel(s.x[i], s.y[i]);
        const double w = char_w * double(label.size());
        // Right, left, above, below, then the diagonals; the first that touches nothing, or
        // the least covered.
        const double cand[8][2] = {{8, -text_h / 2}, {-8 - w, -text_h / 2}, {-w / 2, -8 - text_h}, {-w / 2, 8},
                                   {8, -8 - text_h}, {8, 8},              {-8 - w, -8 - text_h}, {-8 - w, 8}};
        double best = 1e300;
        Box chosen{};
        for (const auto& c : cand) {
          const Box b{u + c[0], v + c[1], u + c[0] + w, v + c[1] + text_h};
          double cover = 0;
          for (const Box& t : taken) cover += b.overlap(t);
          if (b.x0 < left * width || b.x1 > right * width || b.y0 < (1 - top) * height || b.y1 > (1 - bottom) * height) cover += 1e6;
          if (cover < best) best = cover, chosen = b, dx = c[0], dy = c[1];
          if (cover == 0) break;
        }
        taken.push_back(chosen);
      }
      // The label's anchor (its left end, vertically centred) back in data coordinates.
      const auto [u, v] = pixel(s.x[i], s.y[i]);
      const double au = u + dx, av = v + dy + text_h / 2;
      double lx = x0 + ((au / width - left) / (right - left)) * (x1 - x0);
      if (log_x) lx = std::pow(10.0, lx);
      const double ly = y0 + ((1 - av / height - bottom) / (top - bottom)) * (y1 - y0);
      // The series by its index (names go into the script: gnuplot splits quoted commas).
      csv << k << "," << number(s.x[i]) << "," << number(s.y[i]) << "," << csv_field(label) << ","
          << (label.empty() ? "NaN" : number(lx)) << "," << (label.empty() ? "NaN" : number(ly)) << "," << csv_field(s.name) << "\n";
      if (!label.empty())
        placed << "set label " << quoted(label) << " at " << number(lx) << ", " << number(ly) << " left font ',9' tc rgb '"
               << kPalette[k % 6] << "'\n";
    }
  }
  const std::string data = fs::path(path).stem().string() + ".csv";
  std::ostringstream gp;
  gp << title_lines(labels) << "set lmargin at screen " << left << "\nset rmargin at screen " << right << "\nset bmargin at screen "
     << bottom << "\nset tmargin at screen " << top << "\n"
     << "set key outside right top vertical Left reverse noautotitle\n"
     << "set grid xtics ytics lc rgb '#dddddd' lt 1\n";
  if (log_x) gp << "set logscale x 10\nset format x '%g'\nset xrange [" << number(std::pow(10.0, x0)) << ":" << number(std::pow(10.0, x1)) << "]\n";
  else gp << "set xrange [" << number(x0) << ":" << number(x1) << "]\n";
  gp << "set yrange [" << number(y0) << ":" << number(y1) << "]\n";
  gp << placed.str() << "plot ";
  for (size_t k = 0; k < series.size(); ++k) {
    const std::string colour = kPalette[k % 6];
    const std::string mine = "($1 == " + std::to_string(k) + " ? $";
    if (k) gp << ", \\\n     ";
    gp << "'" << data << "' skip 1 using 2:" << mine << "3 : NaN) with " << (series[k].joined ? "linespoints" : "points") << " pt 7 ps 1.1 lw 1.5 lc rgb '" << colour << "' title "
       << quoted(series[k].name);
  }
  gp << "\n";
  draw(path, csv.str(), gp.str(), width, height);

}


void write_heatmap_png(const std::string& path, const std::vector<float>& values, int rows, int cols, const PlotLabels& labels,
                       const std::vector<double>* row_totals) {
  FILLGS_CHECK(rows > 0 && cols > 0);
  FILLGS_CHECK_EQ(values.size(), size_t(rows) * size_t(cols));
  if (row_totals) FILLGS_CHECK_EQ(row_totals->size(), size_t(rows));
  if (!labels.row_names.empty()) FILLGS_CHECK_EQ(labels.row_names.size(), size_t(rows));
  // CSV: one row of the matrix per line (row 0 first), then, when given, the row sums in a
  // last column.
  std::ostringstream csv;
  csv << "# " << rows << " rows x " << cols << " columns" << (row_totals ? ", then the row sum" : "") << "\n";
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) csv << (c ? "," : "") << number(values[size_t(r) * size_t(cols) + size_t(c)]);
    if (row_totals) csv << "," << number((*row_totals)[size_t(r)]);
    csv << "\n";
  }
  double vmax = 0;
  for (float v : values)
    if (std::isfinite(v)) vmax = std::max(vmax, double(v));
  if (vmax <= 0) vmax = 1;
  const std::string data = fs::path(path).stem().string() + ".csv";
  const double split = row_totals ? 0.74 : 0.86;
  std::ostringstream gp;
  gp << "set multiplot\n" << title_lines(labels)
     << "set lmargin at screen 0.09\nset rmargin at screen " << split << "\nset bmargin at screen 0.12\nset tmargin at screen 0.88\n"
     << "set palette defined (0 '#000004', 1 '#420a68', 2 '#932667', 3 '#dd513a', 4 '#fca50a', 5 '#fcffa4')\n"
     << "set cbrange [0:" << number(vmax) << "]\nset colorbox user origin screen " << split + (row_totals ? 0.20 : 0.02) << ", 0.12 size screen 0.02, 0.76\n"
     << "set xrange [-0.5:" << cols - 0.5 << "]\nset yrange [" << rows - 0.5 << ":-0.5]\nset border 15\nunset grid\n"
     << ytic_names(labels.row_names)
     << "plot '" << data << "' matrix using 1:2:3 with image notitle\n";  // the xrange leaves out the row sums

  if (row_totals) {
    double tmax = 0;
    for (double t : *row_totals)
      if (std::isfinite(t)) tmax = std::max(tmax, t);
    if (tmax <= 0) tmax = 1;
    gp << "unset title\nunset colorbox\nset lmargin at screen " << split + 0.01 << "\nset rmargin at screen " << split + 0.16 << "\n"
       << "set xlabel 'row sum'\nunset ylabel\nset ytics auto\nset format y ''\nset xtics norotate (" << quoted("0") << " 0, " << quoted(compact(tmax))
       << " " << number(tmax) << ")\nset xrange [0:" << number(tmax * 1.02) << "]\n"
       << "plot '" << data << "' using ($" << cols + 1 << "/2):($0):($" << cols + 1
       << "/2):(0.4) with boxxyerror lc rgb '#3c78b4' notitle\n";
  }
  gp << "unset multiplot\n";
  draw(path, csv.str(), gp.str(), int(std::clamp(cols * 8 + 300, 720, 1400)), int(std::clamp(rows * 6 + 200, 420, 900)));
}

}  // namespace fillgs
