#include "fillgs/io/model_formats.hpp"

#include <filesystem>
#include <fstream>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/io/ply.hpp"

namespace fs = std::filesystem;

namespace fillgs {

namespace model_io {
std::vector<const ModelFormat*> rows();  // generated from src/io/formats/ (src/row_table.cpp.in)
}  // namespace model_io

FormatProbe::FormatProbe(std::string path) : path_(std::move(path)) {
  std::error_code ec;
  directory_ = fs::is_directory(path_, ec);
}

std::string FormatProbe::filename() const { return fs::path(path_).filename().string(); }

bool FormatProbe::beside(const std::string& name, bool folder) const {
  std::error_code ec;
  const fs::path p = (directory_ ? fs::path(path_) : fs::path(path_).parent_path()) / name;
  return folder ? fs::is_directory(p, ec) : fs::exists(p, ec);
}

const std::string& FormatProbe::ply_header() const {
  if (header_read_ || directory_) return header_;
  header_read_ = true;
  // The first bytes first: a large file that is no PLY is not read up to a newline.
  char magic[3] = {0, 0, 0};
  std::ifstream in(path_, std::ios::binary);
  if (in.read(magic, 3) && std::string(magic, 3) == "ply") header_ = read_ply_header(path_);
  return header_;
}

const RowTable<ModelFormat>& model_format_table() {
  static const RowTable<ModelFormat> table("scene format", model_io::rows(), {"auto"});
  return table;
}

const std::vector<const ModelFormat*>& model_formats() { return model_format_table().rows(); }

std::string model_format_names() {
  std::vector<std::string> names;
  for (const ModelFormat* f : model_formats()) names.push_back(f->name);
  return join_names(names);
}

const ModelFormat& model_format(const std::string& name) { return model_format_table().find(name); }

const ModelFormat* find_model_format(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw_error(path, ": no such file or directory");
  // A named pipe or a device is refused before any row opens it (a pipe would block).
  if (!fs::is_directory(path, ec)) require_regular_file(path);
  const FormatProbe probe(path);
  const ModelFormat* found = nullptr;
  for (const ModelFormat* f : model_formats()) {
    if (!f->detect(probe)) continue;
    if (!probe.directory()) return f;  // a file: the most specific format that claims it
    // A folder holding two models (params.npz and a chkpnt*.pth) is not read as whichever
    // format detection asks first: the user says which.
    if (found)
      throw_error(path, ": holds both a ", found->name, " model and a ", f->name, " model; give --scene-format ", found->name, " or ",
                  f->name);
    found = f;
  }
  return found;
}

}  // namespace fillgs
