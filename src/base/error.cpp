#include "fillgs/base/error.hpp"

#include <cstdio>
#include <cstdlib>

namespace fillgs::internal {

void check_failed(const char* file, int line, const char* expr, const std::string& detail) {
  std::fprintf(stderr, "fillgs: internal check failed at %s:%d: %s%s%s\n", file, line, expr,
               detail.empty() ? "" : " (", detail.empty() ? "" : (detail + ")").c_str());
  std::abort();
}

}  // namespace fillgs::internal
