// Charts through gnuplot (src/io/chart.cpp): the CSV beside each figure holds exactly the
// numbers given, the script re-plots from it alone, the PNG is whole, and without gnuplot a
// run goes on with the CSV and script and one warning line.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/html_report.hpp"
#include "fillgs/io/image_io.hpp"
#include "fillgs/io/plot.hpp"
#include "helpers.hpp"

using namespace fillgs;
using namespace fillgs::test;
namespace fs = std::filesystem;

namespace {

bool have_gnuplot() { return std::system("gnuplot -e 'exit' >/dev/null 2>&1") == 0; }

std::vector<std::vector<std::string>> csv_rows(const std::string& path) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> fields;
    std::string field;
    bool quoted = false;
    for (size_t i = 0; i < line.size(); ++i) {
      const char c = line[i];
      if (c == '"') {
        if (quoted && i + 1 < line.size() && line[i + 1] == '"') field += '"', ++i;
        else quoted = !quoted;
      } else if (c == ',' && !quoted) {
        fields.push_back(field), field.clear();
      } else {
        field += c;
      }
    }
    fields.push_back(field);
    rows.push_back(fields);
  }
  return rows;
}

/// Fraction of the image's pixels that are not white: a drawn chart has ink.
double ink(const Image& im) {
  size_t dark = 0;
  for (size_t p = 0; p < size_t(im.width) * im.height; ++p)
    dark += im.pixels[p * size_t(im.channels)] < 0.9f || im.pixels[p * size_t(im.channels) + 1] < 0.9f;
  return double(dark) / (double(im.width) * im.height);
}

}  // namespace

TEST_CASE("bar chart: the CSV holds the names and values, the script re-plots it alone", "[plot]") {
  if (!have_gnuplot()) {
    WARN("skipped: no gnuplot (Debian gnuplot-nox; scripts/install-deps.sh installs it)");
    return;
  }
  const std::string dir = scratch("plot_bars");
  const std::vector<std::string> names = {"no-refinement", "coverage4d", "a, \"quoted\" name", "fillgs"};
  const std::vector<double> values = {18.57, 21.95, 0.0125, 18.71};
  write_bar_chart_png(join_path(dir, "bars.png"), names, values, {"interpolation PSNR", "", "PSNR (dB)"});
  const auto rows = csv_rows(join_path(dir, "bars.csv"));
  REQUIRE(rows.size() == 5);
  CHECK(rows[0] == std::vector<std::string>{"name", "value", "label"});
  for (size_t i = 0; i < names.size(); ++i) {
    CHECK(rows[i + 1][0] == names[i]);
    CHECK(std::stod(rows[i + 1][1]) == Approx(values[i]).epsilon(1e-8));
  }
  CHECK(rows[1][2] == "18.57");  // the value written on the bar
  CHECK(rows[3][2] == "0.0125");
  const Image im = read_image(join_path(dir, "bars.png"));
  CHECK(im.width >= 640);
  CHECK(ink(im) > 0.02);
  // The script alone, run where it lies, draws the same figure.
  fs::remove(join_path(dir, "bars.png"));
  REQUIRE(std::system(("cd '" + dir + "' && gnuplot bars.gp").c_str()) == 0);
  const Image again = read_image(join_path(dir, "bars.png"));
  CHECK(again.width == im.width);
  CHECK(again.pixels == im.pixels);
  // No temporary files are left beside it.
  for (const auto& e : fs::directory_iterator(dir)) CHECK(e.path().filename().string()[0] != '.');
}

TEST_CASE("scatter plot: labels placed apart, legend outside the plot, log x", "[plot]") {
  if (!have_gnuplot()) {
    WARN("skipped: no gnuplot (Debian gnuplot-nox; scripts/install-deps.sh installs it)");
    return;
  }
  const std::string dir = scratch("plot_scatter");
  // Four points almost on top of each other: their labels must not share a place.
  ScatterSeries a{"raytraced", {3.0, 3.1, 3.2, 40}, {0.95, 0.951, 0.952, 0.99}, {"stride 8", "stride 4", "stride 2", "stride 1"}};
  ScatterSeries b{"frustum", {0.5, 1}, {0.8, 0.85}, {}};
  write_scatter_png(join_path(dir, "pareto.png"), {a, b}, {"time against recall", "time (s)", "recall"}, true);
  const auto rows = csv_rows(join_path(dir, "pareto.csv"));
  REQUIRE(rows.size() == 7);
  CHECK(rows[0] == std::vector<std::string>{"series", "x", "y", "label", "label_x", "label_y", "series_name"});
  CHECK(rows[1][0] == "0");
  CHECK(rows[1][6] == "raytraced");
  CHECK(rows[5][6] == "frustum");
  // Label anchors differ pairwise by at least a text line vertically or a label's width.
  for (size_t i = 1; i <= 4; ++i)
    for (size_t j = i + 1; j <= 4; ++j) {
      const double dx = std::log10(std::stod(rows[i][4])) - std::log10(std::stod(rows[j][4]));
      const double dy = std::stod(rows[i][5]) - std::stod(rows[j][5]);
      INFO(rows[i][3] << " and " << rows[j][3]);
      CHECK((std::fabs(dy) > 0.004 || std::fabs(dx) > 0.15));
    }
  CHECK(rows[5][3].empty());
  CHECK(rows[5][4] == "NaN");
  CHECK(ink(read_image(join_path(dir, "pareto.png"))) > 0.01);
}

TEST_CASE("heatmap: the matrix and row sums in the CSV, rows in order", "[plot]") {
  if (!have_gnuplot()) {
    WARN("skipped: no gnuplot (Debian gnuplot-nox; scripts/install-deps.sh installs it)");
    return;
  }
  const std::string dir = scratch("plot_heat");
  const int rows = 6, cols = 9;
  std::vector<float> v(size_t(rows * cols));
  std::vector<double> sums(rows, 0.0);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) sums[size_t(r)] += v[size_t(r * cols + c)] = float(r * 10 + c);
  write_heatmap_png(join_path(dir, "heat.png"), v, rows, cols, {"deficiency", "time step", "camera"}, &sums);
  const auto csv = csv_rows(join_path(dir, "heat.csv"));
  REQUIRE(csv.size() == size_t(rows));
  for (int r = 0; r < rows; ++r) {
    REQUIRE(csv[size_t(r)].size() == size_t(cols + 1));
    for (int c = 0; c < cols; ++c) CHECK(std::stod(csv[size_t(r)][size_t(c)]) == v[size_t(r * cols + c)]);
    CHECK(std::stod(csv[size_t(r)][size_t(cols)]) == sums[size_t(r)]);
  }
  CHECK(ink(read_image(join_path(dir, "heat.png"))) > 0.2);
  // Named rows: each name at its row in the script.
  PlotLabels named{"chosen", "frame", "camera"};
  named.row_names = {"cam a", "b", "c's", "d", "e", "f"};
  write_heatmap_png(join_path(dir, "named.png"), v, rows, cols, named, &sums);
  const std::string gp = read_file(join_path(dir, "named.gp"));
  CHECK(gp.find("set ytics ('cam a' 0, 'b' 1, 'c''s' 2, 'd' 3, 'e' 4, 'f' 5)") != std::string::npos);
  CHECK(ink(read_image(join_path(dir, "named.png"))) > 0.2);
}

TEST_CASE("interval chart: each row's intervals in the CSV, separated only where 0 lies outside", "[plot]") {
  if (!have_gnuplot()) {
    WARN("skipped: no gnuplot (Debian gnuplot-nox; scripts/install-deps.sh installs it)");
    return;
  }
  const std::string dir = scratch("plot_interval");
  const double nan = std::nan("");
  // Row 1 of the second series has no interval (one seed): its line is left out.
  const IntervalSeries a{"interpolation", {0.5, -0.1, -0.6}, {0.2, -0.5, -1.0}, {0.8, 0.3, -0.1}};
  const IntervalSeries b{"extrapolation", {0.0, nan, 1.0}, {-0.4, nan, 0.0}, {0.4, nan, 2.0}};
  write_interval_chart_png(join_path(dir, "iv.png"), {"negative", "random", "coverage4d's"}, {a, b}, {"FillGS minus each", "dB", ""});
  const auto csv = csv_rows(join_path(dir, "iv.csv"));
  REQUIRE(csv.size() == 6);
  CHECK(csv[0] == std::vector<std::string>{"series", "y", "estimate", "low", "high", "separated", "row_name", "series_name"});
  // series, y (row -/+ a quarter for two series), estimate, low, high, separated
  const double want[5][6] = {{0, -0.25, 0.5, 0.2, 0.8, 1}, {0, 0.75, -0.1, -0.5, 0.3, 0}, {0, 1.75, -0.6, -1.0, -0.1, 1},
                             {1, 0.25, 0.0, -0.4, 0.4, 0}, {1, 2.25, 1.0, 0.0, 2.0, 0}};  // [0, 2] touches 0: not separated
  for (size_t i = 0; i < 5; ++i)
    for (size_t k = 0; k < 6; ++k) CHECK(std::stod(csv[i + 1][k]) == Approx(want[i][k]).margin(1e-12));
  CHECK(csv[3][6] == "coverage4d's");
  const std::string gp = read_file(join_path(dir, "iv.gp"));
  CHECK(gp.find("set ytics ('negative' 0, 'random' 1, 'coverage4d''s' 2)") != std::string::npos);
  CHECK(ink(read_image(join_path(dir, "iv.png"))) > 0.01);
}

TEST_CASE("without gnuplot a chart leaves its CSV and script, one warning and no PNG", "[plot]") {
  const std::string dir = scratch("plot_missing");
  const EnvOverride no_gnuplot("FILLGS_GNUPLOT", "/nonexistent/gnuplot");
  std::ostringstream captured;
  std::streambuf* old = std::cerr.rdbuf(captured.rdbuf());
  write_bar_chart_png(join_path(dir, "bars.png"), {"a", "b"}, {1.0, 2.0}, {"t", "x", "y"});
  std::cerr.rdbuf(old);
  CHECK(!fs::exists(join_path(dir, "bars.png")));
  CHECK(fs::exists(join_path(dir, "bars.csv")));
  CHECK(fs::exists(join_path(dir, "bars.gp")));
  const std::string warning = captured.str();
  INFO(warning);
  CHECK(std::count(warning.begin(), warning.end(), '\n') == 1);
  CHECK(warning.find("bars.png not drawn") != std::string::npos);
  for (const auto& e : fs::directory_iterator(dir)) CHECK(e.path().filename().string()[0] != '.');
}

namespace {

std::string unbase64(const std::string& text) {
  auto value = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    return c == '+' ? 62 : c == '/' ? 63 : -1;
  };
  std::string out;
  int bits = 0, acc = 0;
  for (char c : text) {
    const int v = value(c);
    if (v < 0) break;  // '=' padding ends it
    acc = (acc << 6) | v, bits += 6;
    if (bits >= 8) bits -= 8, out += char((acc >> bits) & 0xff);
  }
  return out;
}

}  // namespace

TEST_CASE("HTML report: tables, escapes, code and images embedded byte for byte", "[plot][report]") {
  const std::string dir = scratch("html_report");
  Image im(5, 3, 3);
  for (size_t i = 0; i < im.pixels.size(); ++i) im.pixels[i] = float(i % 4) / 3.0f;
  write_image(join_path(dir, "pic.png"), im);
  std::ofstream(join_path(dir, "r.md")) << "# A <report>\n\nSome **bold** and `code`\ncontinued.\n\n"
                                           "| Method | PSNR |\n|---|---|\n| fillgs | 18.71 |\n| a<b | 1 |\n\n"
                                           "- one\n- two\n\n```\nfillgs run --out <dir>\n```\n\n![pic](pic.png)\n\n![gone](gone.png)\n";
  std::ostringstream captured;
  std::streambuf* old = std::cerr.rdbuf(captured.rdbuf());
  const HtmlReport r = write_html_report(join_path(dir, "r.md"), join_path(dir, "r.html"));
  std::cerr.rdbuf(old);
  const std::string& h = r.html;
  CHECK(read_file(join_path(dir, "r.html")) == h);
  CHECK(h.find("<title>A &lt;report&gt;</title>") != std::string::npos);
  CHECK(h.find("<h1>A &lt;report&gt;</h1>") != std::string::npos);
  CHECK(h.find("<p>Some <b>bold</b> and <code>code</code> continued.</p>") != std::string::npos);
  CHECK(h.find("<tr><th>Method</th><th>PSNR</th></tr>") != std::string::npos);
  CHECK(h.find("<tr><td>fillgs</td><td>18.71</td></tr>") != std::string::npos);
  CHECK(h.find("<tr><td>a&lt;b</td><td>1</td></tr>") != std::string::npos);
  CHECK(h.find("<ul>\n<li>one</li>\n<li>two</li>\n</ul>") != std::string::npos);
  CHECK(h.find("<pre><code>fillgs run --out &lt;dir&gt;\n</code></pre>") != std::string::npos);
  CHECK(r.images == std::vector<std::string>{"pic.png", "gone.png"});
  CHECK(r.missing == std::vector<std::string>{"gone.png"});
  CHECK(captured.str().find("gone.png is missing") != std::string::npos);
  const std::string key = "src=\"data:image/png;base64,";
  const size_t at = h.find(key);
  REQUIRE(at != std::string::npos);
  const std::string payload = h.substr(at + key.size(), h.find('"', at + key.size()) - at - key.size());
  CHECK(unbase64(payload) == read_file(join_path(dir, "pic.png")));
  CHECK(h.find("missing image gone.png") != std::string::npos);
}
