#pragma once
// File-system helpers: atomic writes, reading whole files, shared-data lookup.
#include <functional>
#include <string>
#include <vector>

namespace fillgs {

/// Writes `path` atomically: `write` fills a temporary file beside it (same extension, so
/// format-by-extension writers work), which is renamed over `path` only if `write` returns
/// without throwing. Creates missing parent directories.
void write_atomically(const std::string& path, const std::function<void(const std::string& tmp)>& write);

/// Writes bytes atomically.
void write_file_atomically(const std::string& path, const std::string& bytes);

/// Reads a whole file; throws "PATH: cannot open (reason)".
std::string read_file(const std::string& path);

/// Creates a directory (and parents); throws naming it on failure.
void make_directories(const std::string& path);

/// Joins path components with '/'.
std::string join_path(const std::string& a, const std::string& b);

/// The shared real data (scenes, captured video): $FILLGS_SHARED_DATA when set, else
/// ../shared/data beside the source tree (fixed when fillgs is built).
std::string shared_data_dir();

/// A command's output folder, written as one transaction. Everything goes into a hidden
/// staging folder beside it (".<name>.partial-<pid>-<n>"); commit() moves the staged files
/// into place (the folder itself by one rename when it did not exist, else file by file,
/// each replacing the file of that name and leaving the folder's other files alone). A
/// command that throws, or is killed, before commit() leaves an existing folder exactly as
/// it was and creates nothing that stays: the destructor removes the staging folder and any
/// parent folders it had to create, and staging folders and temporary files of processes
/// that no longer run are removed when the next command opens the same folder.
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
  void remove_created_parents();
};

}  // namespace fillgs
