#pragma once
// File-system helpers: atomic writes, reading whole files, shared-data lookup.
#include <functional>
#include <string>
#include <vector>

namespace fillgs {

/// Writes `path` atomically: `write` fills a temporary file beside it (same extension, so
/// format-by-extension writers work), which is renamed over `path` only if `write` returns
/// without throwing and the file did not reach the process's file-size limit (a writer
/// that ignores a failed write would otherwise leave a truncated file that looks whole).
/// Creates missing parent directories.
void write_atomically(const std::string& path, const std::function<void(const std::string& tmp)>& write);

/// Writes bytes atomically.
void write_file_atomically(const std::string& path, const std::string& bytes);

/// Writes `size` bytes to `file` (created or truncated), checking every write and the
/// close: a full disk, a file-size limit or an I/O error throws one line naming `shown`
/// (the path the user knows: the output, not its temporary sibling) and the reason.
void write_file_checked(const std::string& file, const std::string& shown, const void* data, size_t size);

/// Reads a whole file; throws "PATH: cannot open (reason)". Refuses what is not a regular
/// file (require_regular_file).
std::string read_file(const std::string& path);

/// Throws one line naming `path` unless it is a regular file (links followed): a named pipe
/// would hang the reader, /dev/zero would be read until memory runs out, a folder is not a file.
/// Also refuses a file below a folder (up to three levels up) that holds
/// ".fillgs-commit-incomplete": a fillgs commit into it was killed half-way (OutputFolder).
void require_regular_file(const std::string& path);

/// Throws one line naming `path` when it exists and is not a regular file (links followed):
/// an output never replaces a device, a pipe or a folder (as root, `--out /dev/null` would
/// otherwise replace the system's /dev/null with a file). write_atomically calls it first.
void require_replaceable(const std::string& path);

/// FNV-1a (64-bit) of `bytes`, as 16 lower-case hex digits: a file's fingerprint, to tell
/// whether a model made again is the one a record names (not a cryptographic hash).
std::string fnv1a64_hex(const std::string& bytes);

/// Creates a directory (and parents); throws naming it on failure.
void make_directories(const std::string& path);

/// Joins path components with '/'.
std::string join_path(const std::string& a, const std::string& b);

/// The shared real data (scenes, captured video): $FILLGS_SHARED_DATA when set, else
/// ../shared/data beside the source tree (fixed when fillgs is built).
std::string shared_data_dir();

/// `message` with the staging folder of every OutputFolder of this process replaced by its output
/// folder: an error met while writing names the path the user gave, not a hidden one.
std::string output_paths(std::string message);

/// Marks a folder that a long command (train, finetune) writes into directly, so that it
/// can resume from its checkpoints, as unfinished while it runs: "DIR/.fillgs-unfinished"
/// is written (and locked) first and removed by finish() last. A command killed or failed
/// half-way leaves the marker, and the folder says it is unfinished. A second command on a
/// folder whose marker a live run holds is refused with one line. Temporary files that
/// killed runs left in the folder (unlocked) are removed when the marker is taken.
class UnfinishedMarker {
 public:
  UnfinishedMarker(const std::string& dir, const std::string& command);
  ~UnfinishedMarker();
  UnfinishedMarker(const UnfinishedMarker&) = delete;
  UnfinishedMarker& operator=(const UnfinishedMarker&) = delete;
  void finish();
  /// The marker's path in `dir`, and whether a run left it there (unfinished).
  static std::string path_in(const std::string& dir);
  static bool present(const std::string& dir);

 private:
  std::string path_;
  int fd_ = -1;
};

/// A hidden name beside `path` for its temporary file (".<stem>.fillgs-tmp-<token><ext>",
/// same extension, so format-by-extension writers work).
std::string temporary_name(const std::string& path);

/// Removes from `dir` (three levels down) the temporary files and staging folders that
/// killed fillgs runs left there, proved by the locks nobody holds; nothing else. For
/// folders a command writes directly (train, finetune, bench), before it writes.
void remove_stale_temporaries(const std::string& dir);

/// A temporary file beside `beside` (temporary_name), created and locked for this object's
/// life and removed by its destructor (unless renamed away meanwhile): what
/// write_atomically writes into, a helper program's log. A process killed while it
/// exists leaves an unlocked file that the next command on the folder removes.
class LockedTemporary {
 public:
  explicit LockedTemporary(const std::string& beside);
  ~LockedTemporary();
  LockedTemporary(const LockedTemporary&) = delete;
  LockedTemporary& operator=(const LockedTemporary&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
};

/// A command's output folder, written as one transaction. Everything goes into a hidden
/// staging folder on the output's own file system — beside a new folder
/// (".<name>.fillgs-staging-<token>"), inside an existing one (".fillgs-staging-<token>") —
/// and commit() moves the staged files into place: a new folder by one rename, an existing
/// one file by file, each replacing the file of that name and leaving the folder's other
/// files alone, with ".fillgs-commit-incomplete" in the folder while the files move (a commit
/// killed then leaves it: readers refuse the folder's files, the next commit removes it). A command that throws, or is killed, before commit() leaves an existing
/// folder exactly as it was and creates nothing that stays: the destructor removes the
/// staging folder and any parent folders it had to create. An existing folder is locked
/// (flock) while the command runs, so a second command on it is refused with one line.
/// The staging folder holds a lock file for its life; the next command on the same output
/// removes a staging folder whose lock nobody holds and temporary files nobody holds (the
/// leftovers of killed runs, in any PID namespace), and nothing else, whatever its name.
class OutputFolder {
 public:
  explicit OutputFolder(const std::string& dir);
  ~OutputFolder();
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;
  /// Where to write until commit().
  const std::string& path() const { return staging_; }
  void commit();

 private:
  std::string dir_, staging_;
  std::vector<std::string> created_;  ///< parent folders this object created, outermost first
  bool committed_ = false;
  int dir_fd_ = -1, lock_fd_ = -1;    ///< the existing folder's lock, the staging folder's lock file
  void remove_created_parents();
  void release();
};

}  // namespace fillgs
