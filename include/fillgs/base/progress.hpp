#pragma once
// Progress reporting through an interface: the library reports, front ends display.
#include <cstddef>
#include <string>

namespace fillgs {

class Progress {
 public:
  virtual ~Progress() = default;
  virtual void start(const std::string& label, size_t total) = 0;
  virtual void advance(size_t steps = 1) = 0;
  virtual void finish() = 0;
  /// A short line about the current state (loss, counts), shown next to the bar.
  virtual void status(const std::string& line) {}
};

/// A reporter that does nothing.
Progress& null_progress();

}  // namespace fillgs
