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

}  // namespace fillgs
