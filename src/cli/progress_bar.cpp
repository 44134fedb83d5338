#include "progress_bar.hpp"

#include <cstdio>

namespace fillgs {
namespace cli {

TerminalProgress::TerminalProgress(std::ostream& err, bool enabled) : err_(err), enabled_(enabled) {}

void TerminalProgress::start(const std::string& label, size_t total) {
  label_ = label;
  total_ = total;
  done_ = 0;
  start_ = last_draw_ = std::chrono::steady_clock::now();
  draw(false);
}

void TerminalProgress::advance(size_t steps) {
  done_ += steps;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_draw_ > std::chrono::milliseconds(100) || done_ >= total_) {
    last_draw_ = now;
    draw(false);
  }
}

void TerminalProgress::finish() { draw(true); }

void TerminalProgress::draw(bool final) {
  if (!enabled_) return;
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
