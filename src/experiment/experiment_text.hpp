#pragma once
// Text helpers the benchmark's plan, runs and reports share (src/experiment/).
#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

namespace fillgs::detail {

/// x with `digits` decimals, "–" where it is not finite (the tables' cells).
inline std::string fmt(double x, int digits = 2) {
  if (!std::isfinite(x)) return "–";
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << x;
  return s.str();
}

/// The comma-separated cells of a CSV line (no quoting: fillgs's files have none); a
/// trailing comma ends in an empty cell.
inline std::vector<std::string> csv_cells(const std::string& line) {
  std::vector<std::string> f;
  std::stringstream ls(line);
  for (std::string cell; std::getline(ls, cell, ',');) f.push_back(cell);
  if (!line.empty() && line.back() == ',') f.emplace_back();
  return f;
}

/// Mean and sample standard deviation of values added one at a time.
struct Moments {
  double sum = 0, squares = 0;
  int n = 0;
  void add(double x) { sum += x, squares += x * x, ++n; }
  double mean() const { return sum / n; }
  double sd() const { return n > 1 ? std::sqrt(std::max(0.0, (squares - sum * sum / n) / (n - 1))) : 0.0; }
};

}  // namespace fillgs::detail
