#include "fillgs/base/bounds.hpp"

#include <cmath>
#include <sstream>

#include "fillgs/base/error.hpp"
#include "fillgs/base/limits.hpp"

namespace fillgs {

std::string number_text(double x) {
  std::ostringstream s;
  s << x;
  return s.str();
}

Bounds at_least(double lo) { return {lo, INFINITY, false, false, "at least " + number_text(lo)}; }
Bounds positive() { return {0.0, INFINITY, true, false, "positive"}; }
Bounds within(double lo, double hi) { return {lo, hi, false, false, "in [" + number_text(lo) + ", " + number_text(hi) + "]"}; }
Bounds within_open(double lo, double hi) { return {lo, hi, true, true, "in (" + number_text(lo) + ", " + number_text(hi) + ")"}; }
Bounds from_below(double lo, double hi) { return {lo, hi, false, true, "in [" + number_text(lo) + ", " + number_text(hi) + ")"}; }

std::string bounds_problem(double x, const Bounds& bounds, const std::string& text) {
  if (bounds.holds(x)) return "";
  return "must be " + (bounds.words.empty() ? "in [" + number_text(bounds.lo) + ", " + number_text(bounds.hi) + "]" : bounds.words) + ", got " +
         (text.empty() ? number_text(x) : text);
}

void check_within(const std::string& what, double x, const Bounds& bounds) {
  // As the command line's parser: NaN and infinities are no numbers (`--tau nan` is refused
  // before its bounds are asked).
  if (!std::isfinite(x)) throw_error(what, " expects a number, got ", number_text(x));
  const std::string why = bounds_problem(x, bounds);
  if (!why.empty()) throw_error(what, " ", why);
}

}  // namespace fillgs

namespace fillgs {

std::string Spelling::operator()(const std::string& key) const {
  if (!flags) return key;
  std::string s = "--" + key;
  for (char& c : s)
    if (c == '_') c = '-';
  return s;
}

std::string check_number(const std::string& text, bool integral, const Bounds& bounds, double* out) {
  double x = 0;
  if (!parse_number(text, &x)) return std::string("expects ") + (integral ? "an integer" : "a number") + ", got '" + text + "'";
  if (integral && x != std::floor(x)) return "expects an integer, got '" + text + "'";
  const std::string why = bounds_problem(x, bounds, text);
  if (!why.empty()) return why;
  *out = x;
  return "";
}

}  // namespace fillgs
