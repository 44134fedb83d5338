#include "fillgs/fs_util.hpp"

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include "fillgs/error.hpp"

namespace fs = std::filesystem;

namespace fillgs {

void make_directories(const std::string& path) {
  if (path.empty()) return;
  std::error_code ec;
  fs::create_directories(path, ec);
  if (ec) throw_error(path, ": cannot create directory (", ec.message(), ")");
}

std::string join_path(const std::string& a, const std::string& b) {
  if (a.empty()) return b;
  return (fs::path(a) / b).string();
}

void write_atomically(const std::string& path, const std::function<void(const std::string&)>& write) {
  static std::atomic<unsigned> counter{0};
  const fs::path target(path);
  if (target.has_parent_path()) make_directories(target.parent_path().string());
  std::ostringstream name;
  name << "." << target.stem().string() << ".tmp" << ::getpid() << "_" << counter++ << target.extension().string();
  const fs::path tmp = target.parent_path() / name.str();
  try {
    write(tmp.string());
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  }
  std::error_code ec;
  fs::rename(tmp, target, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw_error(path, ": cannot write (", ec.message(), ")");
  }
}

void write_file_atomically(const std::string& path, const std::string& bytes) {
  write_atomically(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw_error(path, ": cannot open for writing (", std::strerror(errno), ")");
    out.write(bytes.data(), std::streamsize(bytes.size()));
    out.flush();
    if (!out) throw_error(path, ": write failed (", std::strerror(errno), ")");
  });
}

std::string read_file(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw_error(path, ": is a directory, expected a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_error(path, ": cannot open (", std::strerror(errno), ")");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace fillgs
