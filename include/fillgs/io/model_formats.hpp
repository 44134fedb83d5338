#pragma once
// The model formats fillgs reads, one table (base/row_table.hpp): each format is one file
// under src/io/formats/ that defines its row {heading, detect(path), open(path, options)},
// and the build collects every file there into the table (CMakeLists.txt,
// src/row_table.cpp.in). A format's own parameters (Spacetime Gaussians' duration) are
// declared in its row; the command line's flags and the Python module's keywords are made
// from them, and their values reach it as SceneReadOptions::parameters.
// Adding a format is adding that file (and its test); nothing else names it.
//
// read_scene (io/scene_io.hpp) detects a path's format here, and reads it through its row:
// a format whose own code evaluates it at any time (networks, closed-form slices, frame
// sequences) opens a TrainedModel (io/trained_models.hpp), streamed or sampled into keys as
// the options ask; a file of Gaussians is read whole.
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "fillgs/base/row_table.hpp"
#include "fillgs/io/scene_io.hpp"

namespace fillgs {

class TrainedModel;

/// What detection looks at: the path, and (read once, when first asked) the PLY header of a
/// file that starts with "ply".
class FormatProbe {
 public:
  explicit FormatProbe(std::string path);
  const std::string& path() const { return path_; }
  bool directory() const { return directory_; }
  /// The last component of the path.
  std::string filename() const;
  /// Whether the folder (or, for a file, the folder holding it) has `name` in it; `folder`:
  /// as a folder.
  bool beside(const std::string& name, bool folder = false) const;
  /// The PLY header of a file ("" for a folder or a file that does not start with "ply").
  const std::string& ply_header() const;

 private:
  std::string path_;
  bool directory_ = false;
  mutable bool header_read_ = false;
  mutable std::string header_;
};

/// The heading's name is what --scene-format and load_model(format=) take, its description
/// the codebase and what it saves; detection asks the lower `order` first (the most specific
/// formats are lowest).
struct ModelFormat : RowHeading {
  /// Whether the path (a file or folder that exists) holds this format.
  std::function<bool(const FormatProbe&)> detect;
  /// A model its own code evaluates at any time (null: read() reads the file whole).
  std::function<std::unique_ptr<TrainedModel>(const std::string& path, const SceneReadOptions&)> open;
  /// open()'s model is evaluated at each time a command asks (networks, slices) unless keys
  /// are asked for; false: it is sampled at its frames into keys (frame sequences).
  bool streams = false;
  /// The file's Gaussians (formats without open()).
  std::function<GaussianCloud(const std::string& path, const SceneReadOptions&)> read;
};

/// The table of formats (detection order; "auto" is accepted beside the names).
const RowTable<ModelFormat>& model_format_table();
/// Every format, in detection order.
const std::vector<const ModelFormat*>& model_formats();

/// The format of that name or alias; one line listing the names otherwise.
const ModelFormat& model_format(const std::string& name);

/// The first format, in detection order, that holds `path`; null when none does.
/// Throws for a path that does not exist.
const ModelFormat* find_model_format(const std::string& path);

/// "a, b or c": every format's name, for messages and help.
std::string model_format_names();

}  // namespace fillgs
