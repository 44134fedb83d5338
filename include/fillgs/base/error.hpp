#pragma once
// Errors and assertions.
//
// Every input problem is reported as a fillgs::Error whose message is one line that
// names the file, the element and what was wrong, e.g.
//   "scene.ply: property 'scale_2' missing (vertex element has 14 properties)".
// Front ends catch it, print the line and exit non-zero.
#include <sstream>
#include <stdexcept>
#include <string>

namespace fillgs {

/// An input or usage error: one line saying what, where and why.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

/// A long call stopped by its front end (Ctrl-C in Python, or an exception a progress
/// callback raised), thrown through the library from a Progress: not an input error, so no
/// reader turns it into one; the front end that threw it says what happened.
class Cancelled : public std::exception {
 public:
  const char* what() const noexcept override { return "cancelled"; }
};

/// Builds an Error message from streamable parts: throw_error("a.ply: vertex ", i, " bad").
template <typename... Parts>
[[noreturn]] void throw_error(const Parts&... parts) {
  std::ostringstream os;
  (os << ... << parts);
  throw Error(os.str());
}

namespace internal {
[[noreturn]] void check_failed(const char* file, int line, const char* expr, const std::string& detail);
}  // namespace internal

}  // namespace fillgs

/// Cheap invariant check, kept in release builds. Violations are programming errors.
#define FILLGS_CHECK(expr)                                                        \
  do {                                                                            \
    if (!(expr)) ::fillgs::internal::check_failed(__FILE__, __LINE__, #expr, ""); \
  } while (0)

/// Compares two values and prints both when the check fails.
#define FILLGS_CHECK_OP(a, op, b)                                                     \
  do {                                                                                \
    const auto& fillgs_a_ = (a);                                                      \
    const auto& fillgs_b_ = (b);                                                      \
    if (!(fillgs_a_ op fillgs_b_)) {                                                  \
      std::ostringstream fillgs_os_;                                                  \
      fillgs_os_ << fillgs_a_ << " vs " << fillgs_b_;                                 \
      ::fillgs::internal::check_failed(__FILE__, __LINE__, #a " " #op " " #b,         \
                                       fillgs_os_.str());                             \
    }                                                                                 \
  } while (0)
#define FILLGS_CHECK_EQ(a, b) FILLGS_CHECK_OP(a, ==, b)
#define FILLGS_CHECK_LT(a, b) FILLGS_CHECK_OP(a, <, b)
#define FILLGS_CHECK_LE(a, b) FILLGS_CHECK_OP(a, <=, b)

/// Hot-loop check: vanishes in release builds.
#ifdef NDEBUG
#define FILLGS_DCHECK(expr) \
  do {                      \
  } while (0)
#else
#define FILLGS_DCHECK(expr) FILLGS_CHECK(expr)
#endif
