#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <iostream>
#include <streambuf>

#include "fillgs/cli.hpp"
#include "fillgs/base/memory.hpp"

namespace {

/// Standard output through write(2), keeping the first error: an iostream over stdio
/// reports that a write failed, not why.
class StdoutBuf : public std::streambuf {
 public:
  StdoutBuf() { setp(buf_, buf_ + sizeof buf_); }
  ~StdoutBuf() override { flush(); }
  int error() const { return error_; }
  bool flush() {
    const char* p = pbase();
    while (p < pptr() && error_ == 0) {
      const ssize_t n = ::write(1, p, size_t(pptr() - p));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) error_ = n < 0 ? errno : EIO;
      else p += n;
    }
    setp(buf_, buf_ + sizeof buf_);  // what could not be written is dropped, the error kept
    return error_ == 0;
  }

 protected:
  int_type overflow(int_type c) override {
    if (!flush()) return traits_type::eof();
    if (!traits_type::eq_int_type(c, traits_type::eof())) {
      *pptr() = traits_type::to_char_type(c);
      pbump(1);
    }
    return traits_type::not_eof(c);
  }
  int sync() override { return flush() ? 0 : -1; }

 private:
  char buf_[1 << 14];
  int error_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  fillgs::keep_freed_memory();
  // A closed pipe (`fillgs train | head`) or a file-size limit must fail the write that
  // meets it, not kill the process half-way: the write returns EPIPE or EFBIG, the command
  // goes on or fails with one line, and nothing half-written is committed. (Children get
  // default handlers back: base/process.cpp.)
  std::signal(SIGPIPE, SIG_IGN);
  std::signal(SIGXFSZ, SIG_IGN);
  StdoutBuf buf;
  std::ostream out(&buf);
  std::cout.rdbuf(&buf);  // anything printed to std::cout takes the same checked path
  std::vector<std::string> args(argv + 1, argv + argc);
  const int code = fillgs::cli::run(args, out, std::cerr);
  std::cout.rdbuf(nullptr);
  // What the command printed is part of its result (`info --json > file`): a standard output
  // that could not be written fails the command, after whatever it wrote to files.
  buf.flush();
  if (buf.error() != 0) {
    std::cerr << "error: fillgs: cannot write to standard output (" << std::strerror(buf.error()) << ")"
              << (code == 0 ? "; the files the command wrote are complete" : "") << "\n";
    return code == 0 ? 1 : code;
  }
  return code;
}
