#pragma once
#include <chrono>
#include <ostream>

#include "fillgs/base/progress.hpp"

namespace fillgs::cli {

/// Progress on stderr: a one-line bar redrawn in place where stderr is a terminal; where it is
/// a file or a pipe (`fillgs finetune ... > ft.log 2>&1`), a plain line when a step starts and
/// then at most every 30 s (FILLGS_PROGRESS_SECONDS), flushed, so a log shows how far a long
/// command is. Silent when quiet, and where the stream is not the process's stderr (the tests'
/// in-process runs).
class TerminalProgress : public Progress {
 public:
  TerminalProgress(std::ostream& err, bool enabled);
  void start(const std::string& label, size_t total) override;
  void advance(size_t steps = 1) override;
  void finish() override;
  void status(const std::string& line) override { status_ = line; }

 private:
  enum class Style { Off, Bar, Lines };
  enum class Moment { Started, Running, Done };
  void draw(bool final);
  void line(Moment moment);
  std::ostream& err_;
  Style style_;
  std::string label_, status_;
  size_t total_ = 0, done_ = 0;
  std::chrono::steady_clock::time_point start_, last_draw_, last_line_;
  bool any_line_ = false;
  double line_seconds_ = 30.0;
};

}  // namespace fillgs::cli
