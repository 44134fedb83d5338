#pragma once
#include <chrono>
#include <ostream>

#include "fillgs/base/progress.hpp"

namespace fillgs::cli {

/// A one-line terminal bar on stderr; silent when stderr is not a terminal or when quiet.
class TerminalProgress : public Progress {
 public:
  TerminalProgress(std::ostream& err, bool enabled);
  void start(const std::string& label, size_t total) override;
  void advance(size_t steps = 1) override;
  void finish() override;
  void status(const std::string& line) override { status_ = line; }

 private:
  void draw(bool final);
  std::ostream& err_;
  bool enabled_;
  std::string label_, status_;
  size_t total_ = 0, done_ = 0;
  std::chrono::steady_clock::time_point start_, last_draw_;
};

}  // namespace fillgs::cli
