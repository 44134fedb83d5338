#include "progress_bar.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <iostream>

namespace fillgs {
namespace cli {

TerminalProgress::TerminalProgress(std::ostream& err, bool enabled)
    : err_(err), style_(!enabled ? Style::Off : ::isatty(2) ? Style::Bar : &err == &std::cerr ? Style::Lines : Style::Off) {
  // The interval between lines in a log: FILLGS_PROGRESS_SECONDS (a positive number), else 30.
  if (const char* v = std::getenv("FILLGS_PROGRESS_SECONDS")) {
    char* end = nullptr;
    const double s = std::strtod(v, &end);
    if (end != v && *end == '\0' && s > 0 && s < 1e6) line_seconds_ = s;
  }
}

void TerminalProgress::start(const std::string& label, size_t total) {
  label_ = label;
  total_ = total;
  done_ = 0;
  start_ = last_draw_ = std::chrono::steady_clock::now();
  if (style_ == Style::Lines) line(Moment::Started);
  else draw(false);
}

void TerminalProgress::advance(size_t steps) {
  done_ += steps;
  const auto now = std::chrono::steady_clock::now();
  if (style_ == Style::Lines) {
    if (std::chrono::duration<double>(now - last_line_).count() >= line_seconds_) line(Moment::Running);
    return;
  }
  if (now - last_draw_ > std::chrono::milliseconds(100) || done_ >= total_) {
    last_draw_ = now;
    draw(false);
  }
}

void TerminalProgress::finish() {
  if (style_ == Style::Lines) {
    // A step that wrote a line (one that ran long enough) says when it ended.
    if (any_line_ && std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count() >= line_seconds_) line(Moment::Done);
    return;
  }
  draw(true);
}

void TerminalProgress::line(Moment moment) {
  const auto now = std::chrono::steady_clock::now();
  // A step that starts less than a line interval after the last line waits for the interval:
  // many short steps make no more lines than one long one.
  if (any_line_ && moment == Moment::Started && std::chrono::duration<double>(now - last_line_).count() < line_seconds_) return;
  const double secs = std::chrono::duration<double>(now - start_).count();
  const double frac = total_ ? double(done_) / double(total_) : 1.0;
  char buf[256];
  std::snprintf(buf, sizeof buf, "progress: %s %zu/%zu (%.0f%%) %.0f s", label_.c_str(), done_, total_, 100.0 * frac, secs);
  err_ << buf;
  if (moment == Moment::Done) err_ << ", done";
  else if (frac > 0 && frac < 1) err_ << ", about " << int(secs * (1 - frac) / frac + 0.5) << " s left";
  if (!status_.empty()) err_ << "; " << status_;
  err_ << "\n" << std::flush;
  last_line_ = now;
  any_line_ = true;
}

void TerminalProgress::draw(bool final) {
  if (style_ != Style::Bar) return;
  const double frac = total_ ? double(done_) / double(total_) : 1.0;
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const int width = 30, filled = int(frac * width);
  char buf[256];
  const double eta = frac > 0 ? secs * (1 - frac) / frac : 0;
  std::snprintf(buf, sizeof buf, "\r%-28s [%.*s%*s] %zu/%zu %5.1fs eta %5.1fs", label_.c_str(), filled,
                "##############################", width - filled, "", done_, total_, secs, eta);
  err_ << buf;
  if (!status_.empty()) err_ << "  " << status_ << "\033[K";
  err_ << (final ? "\n" : "") << std::flush;
}

}  // namespace cli
}  // namespace fillgs
