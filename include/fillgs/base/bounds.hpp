#pragma once
// The interval an option's number must lie in, and the one check both faces (the command
// line's flags, the Python module's keywords) make with it, so that a bad value gets the
// same words from either.
#include <limits>
#include <string>

namespace fillgs {

struct Bounds {
  double lo = -std::numeric_limits<double>::infinity(), hi = std::numeric_limits<double>::infinity();
  bool lo_open = false, hi_open = false;
  std::string words;  ///< "at least 1", "in (0, 1)": the message's wording
  /// False for NaN, whatever the bounds.
  bool holds(double x) const { return (lo_open ? x > lo : x >= lo) && (hi_open ? x < hi : x <= hi); }
};
Bounds at_least(double lo);
Bounds positive();
Bounds within(double lo, double hi);       ///< [lo, hi]
Bounds within_open(double lo, double hi);  ///< (lo, hi)
Bounds from_below(double lo, double hi);   ///< [lo, hi)

/// "must be in (0, 1), got 2" where x is outside the bounds (or NaN); empty where it holds.
/// `text` is how the value was written (the command line's text); empty: x printed.
std::string bounds_problem(double x, const Bounds& bounds, const std::string& text = "");

/// Throws fillgs::Error "<what> expects a number, got nan" where x is not finite (the command
/// line's parser refuses such text), "<what> must be ..., got ..." where it is outside the bounds.
void check_within(const std::string& what, double x, const Bounds& bounds);

/// One-line message for text that is not a number (an integer where `integral`) or is
/// outside the bounds ("must be at least 1, got 0"); empty when it is good (the number in
/// *out). The command line's flags and the rows' parameters (base/row_table.hpp) check so.
std::string check_number(const std::string& text, bool integral, const Bounds& bounds, double* out);

/// How a face spells an option in the library's messages: the command line "--pool-budget",
/// the Python module "pool_budget" (the library's key, the module's keyword). A check made
/// once in the library words its sentence for whichever face asked.
struct Spelling {
  bool flags = true;
  std::string operator()(const std::string& key) const;
};

/// x as the messages print it (%g-like: 0.001, 1e+09).
std::string number_text(double x);

}  // namespace fillgs
