#include "fillgs/base/progress.hpp"

namespace fillgs {

Progress& null_progress() {
  struct Null : Progress {
    void start(const std::string&, size_t) override {}
    void advance(size_t) override {}
    void finish() override {}
  };
  static Null n;
  return n;
}

}  // namespace fillgs
