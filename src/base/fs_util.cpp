#include "fillgs/base/fs_util.hpp"

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <csignal>
#include <sys/types.h>
#include <unistd.h>

#include "fillgs/base/error.hpp"

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

namespace {

/// True when the text after `prefix` in `name` starts with the id of a process that no longer runs.
bool owner_is_gone(const std::string& name, const std::string& prefix) {
  if (name.compare(0, prefix.size(), prefix) != 0) return false;
  const char* digits = name.c_str() + prefix.size();
  char* end = nullptr;
  const long pid = std::strtol(digits, &end, 10);
  if (end == digits || pid <= 0) return false;
  return ::kill(pid_t(pid), 0) != 0 && errno == ESRCH;
}

/// Moves everything under `from` into `to`, replacing files of the same name.
void move_into(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::create_directories(to, ec);
  if (ec) throw_error(to.string(), ": cannot create directory (", ec.message(), ")");
  for (const fs::directory_entry& e : fs::directory_iterator(from)) {
    const fs::path target = to / e.path().filename();
    if (e.is_directory() && fs::is_directory(target)) {
      move_into(e.path(), target);
      continue;
    }
    fs::rename(e.path(), target, ec);
    if (ec) throw_error(target.string(), ": cannot move the new output into place (", ec.message(), ")");
  }
}

}  // namespace

OutputFolder::OutputFolder(const std::string& dir) {
  fs::path d = fs::path(dir).lexically_normal();
  if (d.filename().empty()) d = d.parent_path();
  if (d.empty() || d == "." || d == "..") d = fs::absolute(d).lexically_normal();
  dir_ = d.string();
  fs::path parent = d.parent_path();
  if (parent.empty()) parent = ".";
  // Parents that do not exist yet are created now and removed again if nothing is committed.
  std::vector<fs::path> missing;
  std::error_code ec;
  for (fs::path p = parent; !p.empty() && !fs::exists(p, ec); p = p.parent_path()) missing.push_back(p);
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    fs::create_directory(*it, ec);
    if (ec) throw_error(it->string(), ": cannot create directory (", ec.message(), ")");
    created_.push_back(it->string());
  }
  if (fs::exists(d, ec) && !fs::is_directory(d, ec)) throw_error(dir_, ": exists and is not a folder");
  const std::string name = d.filename().string();
  const std::string prefix = "." + name + ".partial-";
  // What killed runs left: their staging folders beside this one, their temporary files in it.
  for (const fs::directory_entry& e : fs::directory_iterator(parent, ec))
    if (owner_is_gone(e.path().filename().string(), prefix)) fs::remove_all(e.path(), ec);
  if (fs::is_directory(d, ec)) {
    std::vector<fs::path> stale;
    // Outputs nest at most a few levels (camera names with '/'): a folder like "." is not walked whole.
    for (auto it = fs::recursive_directory_iterator(d, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
      const fs::directory_entry& e = *it;
      if (it.depth() >= 3) it.disable_recursion_pending();
      const std::string f = e.path().filename().string();
      const size_t at = f.find(".tmp");
      if ((!f.empty() && f[0] == '.' && at != std::string::npos && owner_is_gone(f.substr(at), ".tmp")) ||
          (e.path().parent_path() == d && owner_is_gone(f, ".partial-")))
        stale.push_back(e.path());
    }
    for (const fs::path& p : stale) fs::remove_all(p, ec);
  }
  static std::atomic<unsigned> counter{0};
  const std::string id = std::to_string(::getpid()) + "-" + std::to_string(counter++);
  staging_ = (parent / (prefix + id)).string();
  fs::create_directory(staging_, ec);
  if (ec && fs::is_directory(d, ec)) {
    // The parent is not writable (say --out is a mount point): stage inside the folder.
    staging_ = (d / (".partial-" + id)).string();
    fs::create_directory(staging_, ec);
  }
  if (ec) {
    remove_created_parents();
    throw_error(dir_, ": cannot create the staging folder ", staging_, " (", ec.message(), ")");
  }
}

void OutputFolder::remove_created_parents() {
  std::error_code ec;
  for (auto it = created_.rbegin(); it != created_.rend(); ++it) fs::remove(*it, ec);  // only if still empty
}

OutputFolder::~OutputFolder() {
  if (committed_) return;
  std::error_code ec;
  fs::remove_all(staging_, ec);
  remove_created_parents();
}

void OutputFolder::commit() {
  std::error_code ec;
  if (!fs::exists(dir_, ec)) {
    fs::rename(staging_, dir_, ec);
    if (ec) throw_error(dir_, ": cannot move the new output into place (", ec.message(), ")");
  } else {
    move_into(staging_, dir_);  // also when staging inside dir_: its entries move up one level
    fs::remove_all(staging_, ec);
  }
  committed_ = true;
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

std::string shared_data_dir() {
  if (const char* dir = std::getenv("FILLGS_SHARED_DATA")) return dir;
  return FILLGS_DEFAULT_SHARED_DATA;
}

}  // namespace fillgs
