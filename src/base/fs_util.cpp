#include "fillgs/base/fs_util.hpp"

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <random>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <csignal>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/resource.h>
#include <sys/stat.h>
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

namespace {
/// What a file system entry that is not a regular file is, for a message.
const char* not_a_file(mode_t mode) {
  return S_ISDIR(mode)    ? "is a directory"
         : S_ISFIFO(mode) ? "is a named pipe"
         : S_ISCHR(mode)  ? "is a character device"
         : S_ISBLK(mode)  ? "is a block device"
         : S_ISSOCK(mode) ? "is a socket"
                          : "is not a regular file";
}
}  // namespace

void require_replaceable(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return;  // nothing there (or a dangling link): a new file
  if (S_ISREG(st.st_mode)) return;
  throw_error(path, ": ", not_a_file(st.st_mode), "; fillgs replaces only regular files with its output");
}

void write_atomically(const std::string& path, const std::function<void(const std::string&)>& write) {
  const fs::path target(path);
  require_replaceable(path);
  if (target.has_parent_path()) make_directories(target.parent_path().string());
  // The temporary file exists and is locked (flock) while it is written, so that only a
  // killed writer's leftover is ever swept (OutputFolder), never a live one; whatever
  // happens, it is gone when this returns (renamed, or removed by its destructor).
  const LockedTemporary tmp(path);
  write(tmp.path());
  // A file that reached the file-size limit lost what came after it (SIGXFSZ is ignored,
  // so the write that met the limit failed with EFBIG), whether or not its writer noticed.
  rlimit limit{};
  struct stat st {};
  if (::getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY && ::stat(tmp.path().c_str(), &st) == 0 &&
      rlim_t(st.st_size) >= limit.rlim_cur)
    throw_error(path, ": cannot write (the file-size limit of ", limit.rlim_cur, " bytes was reached; see ulimit -f)");
  std::error_code ec;
  fs::rename(tmp.path(), target, ec);
  if (ec) throw_error(path, ": cannot write (", ec.message(), ")");
}

void write_file_checked(const std::string& file, const std::string& shown, const void* data, size_t size) {
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw_error(shown, ": cannot open for writing (", std::strerror(errno), ")");
  const char* p = static_cast<const char*>(data);
  size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, p + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int e = n < 0 ? errno : ENOSPC;
      ::close(fd);
      throw_error(shown, ": write failed after ", done, " of ", size, " bytes (", std::strerror(e), ")");
    }
    done += size_t(n);
  }
  if (::close(fd) != 0) throw_error(shown, ": write failed (", std::strerror(errno), ")");
}

void write_file_atomically(const std::string& path, const std::string& bytes) {
  write_atomically(path, [&](const std::string& tmp) { write_file_checked(tmp, path, bytes.data(), bytes.size()); });
}

namespace {

/// A name no other program picks: the process id and 64 random bits.
std::string unique_token() {
  static std::atomic<unsigned> counter{0};
  static const uint64_t salt = [] {
    std::random_device rd;
    return (uint64_t(rd()) << 32) ^ uint64_t(rd());
  }();
  char b[64];
  std::snprintf(b, sizeof b, "%d-%016llx-%u", int(::getpid()), static_cast<unsigned long long>(salt), counter++);
  return b;
}

const char* const kStagingMark = ".fillgs-staging-";  ///< a staging folder's name holds this
const char* const kTempMark = ".fillgs-tmp-";          ///< a temporary file's name holds this
const char* const kLockName = ".fillgs-lock";          ///< held (flock) inside a live staging folder
const char* const kIncomplete = ".fillgs-commit-incomplete";  ///< in a folder while a commit moves files into it

/// True when `file` is a regular file (not followed through a link) that no process holds
/// a lock on: its writer ended without cleaning up. A file that cannot be opened or locked
/// for another reason is not proved stale.
bool unlocked_file(const fs::path& file) {
  const int fd = ::open(file.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) return false;
  struct stat st {};
  const bool stale = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && ::flock(fd, LOCK_EX | LOCK_NB) == 0;
  ::close(fd);
  return stale;
}

/// Removes what killed fillgs runs provably left: staging folders (named with kStagingMark
/// and holding an unlocked kLockName) among `folder`'s entries whose names start with
/// `staging_prefix`, and — down to `depth` levels — temporary files (named with kTempMark)
/// that no writer holds. Anything else, whatever its name, is the user's and stays.
void sweep(const fs::path& folder, const std::string& staging_prefix, int depth) {
  std::error_code ec;
  std::vector<fs::path> stale;
  for (auto it = fs::recursive_directory_iterator(folder, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    const fs::directory_entry& e = *it;
    const std::string name = e.path().filename().string();
    if (it.depth() >= depth - 1 || e.is_symlink(ec)) it.disable_recursion_pending();
    if (it.depth() == 0 && name.rfind(staging_prefix, 0) == 0 && e.is_directory(ec) && !e.is_symlink(ec)) {
      it.disable_recursion_pending();
      if (unlocked_file(e.path() / kLockName)) stale.push_back(e.path());
    } else if (name.size() > 1 && name[0] == '.' && name.find(kTempMark) != std::string::npos && unlocked_file(e.path())) {
      stale.push_back(e.path());
    }
  }
  for (const fs::path& p : stale) fs::remove_all(p, ec);
}

const char* const kManifest = ".fillgs-outputs";  ///< what the last command wrote into a folder

/// Every file under `root` (relative paths, '/'-separated, sorted), less `skip` at the top.
std::vector<std::string> files_under(const fs::path& root, const std::string& skip) {
  std::vector<std::string> out;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(root, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (it.depth() == 0 && it->path().filename() == skip) continue;
    if (!it->is_directory(ec)) out.push_back(fs::relative(it->path(), root, ec).generic_string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<std::string> read_manifest_file(const fs::path& file) {
  std::vector<std::string> out;
  std::ifstream in(file);
  for (std::string line; std::getline(in, line);)
    if (!line.empty() && line[0] != '#') out.push_back(line);
  return out;
}

std::vector<std::string> read_manifest(const fs::path& dir) { return read_manifest_file(dir / kManifest); }

std::string manifest_text(const std::vector<std::string>& files) {
  std::string t = "# The files the last fillgs command wrote into this folder; the next one removes those it does not write again.\n";
  for (const std::string& f : files) t += f + "\n";
  return t;
}

/// Moves everything under `from` into `to`, replacing files of the same name; `skip` (a
/// name in `from` itself) stays behind. `moved` counts the files moved so far.
void move_into(const fs::path& from, const fs::path& to, const std::string& skip, size_t& moved) {
  std::error_code ec;
  fs::create_directories(to, ec);
  if (ec) throw_error(to.string(), ": cannot create directory (", ec.message(), ")");
  for (const fs::directory_entry& e : fs::directory_iterator(from)) {
    if (!skip.empty() && e.path().filename() == skip) continue;
    const fs::path target = to / e.path().filename();
    if (e.is_directory() && fs::is_directory(target)) {
      move_into(e.path(), target, "", moved);
      continue;
    }
    fs::rename(e.path(), target, ec);
    if (ec) throw_error(target.string(), ": cannot move the new output into place (", ec.message(), ")");
    moved += e.is_directory() ? 0 : 1;
  }
}

std::mutex staging_mutex;
/// Every staging folder this process made and its output: kept after the folder is gone,
/// since an error is printed after the stack that held it has unwound.
std::vector<std::pair<std::string, std::string>> staging_to_output;

void note_staging(const std::string& staging, const std::string& dir) {
  std::lock_guard<std::mutex> lock(staging_mutex);
  staging_to_output.emplace_back(staging, dir);
}

}  // namespace

std::string output_paths(std::string message) {
  std::lock_guard<std::mutex> lock(staging_mutex);
  for (const auto& [staging, dir] : staging_to_output)
    for (size_t at = message.find(staging); at != std::string::npos; at = message.find(staging, at + dir.size())) message.replace(at, staging.size(), dir);
  return message;
}

std::string temporary_name(const std::string& path) {
  const fs::path target(path);
  return (target.parent_path() / ("." + target.stem().string() + kTempMark + unique_token() + target.extension().string())).string();
}

OutputFolder::OutputFolder(const std::string& dir) {
  fs::path d = fs::path(dir).lexically_normal();
  if (d.filename().empty()) d = d.parent_path();
  if (d.empty() || d == "." || d == "..") d = fs::absolute(d).lexically_normal();
  dir_ = d.string();
  fs::path parent = d.parent_path();
  if (parent.empty()) parent = ".";
  std::error_code ec;
  if (fs::exists(d, ec) && !fs::is_directory(d, ec)) throw_error(dir_, ": exists and is not a folder");
  // Parents that do not exist yet are created now and removed again if nothing is committed.
  std::vector<fs::path> missing;
  for (fs::path p = parent; !p.empty() && !fs::exists(p, ec); p = p.parent_path()) missing.push_back(p);
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    fs::create_directory(*it, ec);
    if (ec) {
      const std::string why = ec.message();
      remove_created_parents();
      throw_error(it->string(), ": cannot create directory (", why, ")");
    }
    created_.push_back(it->string());
  }
  const std::string name = d.filename().string();
  const bool exists = fs::is_directory(d, ec);
  if (exists) {
    // One command at a time writes an existing folder: a second one is refused, not mixed in.
    dir_fd_ = ::open(dir_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dir_fd_ < 0) throw_error(dir_, ": cannot open the folder (", std::strerror(errno), ")");
    if (::flock(dir_fd_, LOCK_EX | LOCK_NB) != 0) {
      const int e = errno;
      ::close(dir_fd_);
      dir_fd_ = -1;
      if (e == EWOULDBLOCK) throw_error(dir_, ": another fillgs command is writing this folder; wait for it, or use another --out");
      throw_error(dir_, ": cannot lock the folder (", std::strerror(e), ")");
    }
  }
  // What killed runs left, proved by their unheld locks: staging folders beside a new output
  // or inside an existing one, temporary files in it.
  sweep(parent, "." + name + kStagingMark, 1);
  if (exists) remove_stale_temporaries(dir_);
  // Staging lies on the output's own file system: inside the folder when it exists (a mount
  // point, a link to another file system), else beside it, where it will be renamed to.
  const std::string token = unique_token();
  staging_ = exists ? (d / (kStagingMark + token)).string() : (parent / ("." + name + kStagingMark + token)).string();
  if (!fs::create_directory(staging_, ec) || ec) {
    const std::string why = ec ? ec.message() : "exists";
    release();
    throw_error(dir_, ": cannot create the staging folder ", staging_, " (", why, ")");
  }
  note_staging(staging_, dir_);
  lock_fd_ = ::open((fs::path(staging_) / kLockName).c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lock_fd_ < 0 || ::flock(lock_fd_, LOCK_EX) != 0) {
    const std::string why = std::strerror(errno);
    fs::remove_all(staging_, ec);
    release();
    throw_error(dir_, ": cannot lock the staging folder ", staging_, " (", why, ")");
  }
}

void OutputFolder::remove_created_parents() {
  std::error_code ec;
  for (auto it = created_.rbegin(); it != created_.rend(); ++it) fs::remove(*it, ec);  // only if still empty
}

void OutputFolder::release() {
  if (lock_fd_ >= 0) ::close(lock_fd_);
  if (dir_fd_ >= 0) ::close(dir_fd_);
  lock_fd_ = dir_fd_ = -1;
  if (!committed_) remove_created_parents();
}

OutputFolder::~OutputFolder() {
  if (!committed_) {
    std::error_code ec;
    fs::remove_all(staging_, ec);
  }
  release();
}

void OutputFolder::commit() {
  std::error_code ec;
  const fs::path lock = fs::path(staging_) / kLockName;
  // The folder keeps a list of what this command wrote, so that the next command on it
  // removes what it does not write again (40 frames, then 10: 10 stay) and nothing else.
  const std::vector<std::string> files = files_under(staging_, kLockName);
  write_file_atomically((fs::path(staging_) / kManifest).string(), manifest_text(files));
  if (!fs::exists(dir_, ec)) {
    // A new folder appears whole, by one rename.
    fs::remove(lock, ec);
    fs::rename(staging_, dir_, ec);
    if (ec) {
      const std::string why = ec.message();
      throw_error(dir_, ": cannot move the new output into place (", why,
                  fs::exists(dir_) ? "; another command created the folder meanwhile, nothing of this run was committed)" : ")");
    }
  } else {
    // An existing folder holds the user's files too, so it cannot be swapped whole: the new
    // files replace the old ones one rename each, then the previous command's files that
    // this one did not write go. A commit that stops half-way says what it left.
    // The moves are many renames: while they run, a marker in the folder says so, with the
    // files being moved. A commit killed half-way leaves it; readers refuse the folder's
    // files (require_regular_file) and the next commit also removes the files it names.
    std::vector<std::string> previous = read_manifest(dir_);
    const fs::path marker = fs::path(dir_) / kIncomplete;
    if (fs::exists(marker, ec)) {
      std::vector<std::string> interrupted = read_manifest_file(marker);
      previous.insert(previous.end(), interrupted.begin(), interrupted.end());
    }
    write_file_atomically(marker.string(), manifest_text(files));
    size_t moved = 0;
    try {
      move_into(staging_, dir_, kLockName, moved);  // also when staging inside dir_: its entries move up one level
    } catch (const Error& e) {
      throw_error(e.what(), "; the commit stopped after ", moved, " of ", files.size(), " new files: ", dir_,
                  " now holds those and the previous run's others (the rest stays in ", staging_, ")");
    }
    fs::remove_all(staging_, ec);
    for (const std::string& old : previous) {
      if (old.empty() || old.find("..") != std::string::npos || old[0] == '/' || std::binary_search(files.begin(), files.end(), old)) continue;
      const fs::path stale = fs::path(dir_) / old;
      if (fs::is_regular_file(fs::symlink_status(stale, ec))) fs::remove(stale, ec);
      // Folders it emptied go too (never the output folder itself).
      for (fs::path p = stale.parent_path(); p != fs::path(dir_) && p.string().size() > dir_.size(); p = p.parent_path())
        if (!fs::remove(p, ec)) break;
    }
    fs::remove(marker, ec);
  }
  committed_ = true;
}

std::string UnfinishedMarker::path_in(const std::string& dir) { return join_path(dir, ".fillgs-unfinished"); }

bool UnfinishedMarker::present(const std::string& dir) {
  std::error_code ec;
  return fs::exists(path_in(dir), ec);
}

UnfinishedMarker::UnfinishedMarker(const std::string& dir, const std::string& command) : path_(path_in(dir)) {
  make_directories(dir);
  fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) throw_error(path_, ": cannot write (", std::strerror(errno), ")");
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd_);
    fd_ = -1;
    throw_error(dir, ": another fillgs command is writing this folder; wait for it, or use another --out");
  }
  const std::string text = "fillgs " + command + " (process " + std::to_string(::getpid()) +
                           ") is writing this folder, or stopped before it finished: its files are not a finished run.\n";
  if (::ftruncate(fd_, 0) != 0 || ::write(fd_, text.data(), text.size()) != ssize_t(text.size()))
    throw_error(path_, ": cannot write (", std::strerror(errno), ")");
  // What a killed run left in the folder it wrote directly (a chart's temporary PNG, its
  // gnuplot log), proved by unheld locks, goes now; this command holds the folder.
  remove_stale_temporaries(dir);
}

void remove_stale_temporaries(const std::string& dir) { sweep(dir, kStagingMark, 3); }

LockedTemporary::LockedTemporary(const std::string& beside) : path_(temporary_name(beside)) {
  fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd_ < 0) throw_error(beside, ": cannot write (", std::strerror(errno), " creating ", path_, ")");
  ::flock(fd_, LOCK_EX);
}

LockedTemporary::~LockedTemporary() {
  std::error_code ec;
  fs::remove(path_, ec);
  ::close(fd_);
}

void UnfinishedMarker::finish() {
  if (fd_ < 0) return;
  std::error_code ec;
  fs::remove(path_, ec);
  ::close(fd_);
  fd_ = -1;
}

UnfinishedMarker::~UnfinishedMarker() {
  if (fd_ >= 0) ::close(fd_);  // not finished: the marker stays
}

void require_regular_file(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw_error(path, ": cannot open (", std::strerror(errno), ")");
  if (S_ISREG(st.st_mode)) {
    // A file of a folder whose commit was killed half-way may be the new run's or the old
    // one's: refused, naming the marker (outputs nest at most three folders deep).
    fs::path dir = fs::path(path).parent_path();
    for (int level = 0; level < 4; ++level) {
      const fs::path marker = (dir.empty() ? fs::path(".") : dir) / kIncomplete;
      if (::stat(marker.c_str(), &st) == 0)
        throw_error(path, ": the fillgs command that wrote ", dir.empty() ? std::string(".") : dir.string(),
                    " was killed while moving its files into place (", marker.string(),
                    " is there), so its files mix two runs; run that command again");
      if (dir.empty() || dir == dir.parent_path()) break;
      dir = dir.parent_path();
    }
    return;
  }
  throw_error(path, ": ", not_a_file(st.st_mode), ", expected a file");
}

std::string fnv1a64_hex(const std::string& bytes) {
  uint64_t h = 0xcbf29ce484222325ull;
  for (const unsigned char c : bytes) h = (h ^ c) * 0x100000001b3ull;
  char out[17];
  std::snprintf(out, sizeof out, "%016llx", static_cast<unsigned long long>(h));
  return out;
}

std::string read_file(const std::string& path) {
  require_regular_file(path);
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
