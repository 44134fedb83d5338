#pragma once
// A small PLY reader and writer (ASCII, binary little- and big-endian).
//
// Scalar properties are read into float columns, looked up by name; list properties
// (faces in mesh files) are parsed and dropped. Errors name the file, the element,
// the record and the property.
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace fillgs {

enum class PlyFormat { Ascii, BinaryLittleEndian, BinaryBigEndian };

/// One element's scalar properties as float columns.
class PlyElement {
 public:
  std::string name;
  size_t count = 0;
  std::vector<std::string> property_names;  ///< scalar properties in file order
  std::vector<std::vector<float>> columns;  ///< one per scalar property

  bool has(const std::string& property) const;
  /// The column of `property`; throws "FILE: property 'p' missing (vertex element has N properties)".
  const std::vector<float>& column(const std::string& property) const;
  /// As column(), but also throws "FILE: vertex 17 property 'scale_0' is NaN" on non-finite values.
  const std::vector<float>& finite_column(const std::string& property) const;
  /// Names matching `prefix` followed by a decimal index (f_rest_0, f_rest_1, ...), sorted by index.
  std::vector<std::string> indexed_properties(const std::string& prefix) const;

  std::string source;  ///< file name used in error messages
  size_t first_row = 0;  ///< a block of an element's rows (PlyElementSink): its first row's index, for messages
};

struct PlyData {
  PlyFormat format = PlyFormat::BinaryLittleEndian;
  std::vector<std::string> comments;
  std::vector<PlyElement> elements;
  /// The named element; throws naming the file if it is absent.
  const PlyElement& element(const std::string& name) const;
  const PlyElement* find(const std::string& name) const;
};

/// An element whose rows a reader takes in blocks instead of as whole columns, so that they
/// are held once, in the reader's own arrays.
struct PlyElementSink {
  std::string element;
  /// Before the element's rows: what is read so far (format, comments, the elements before
  /// it) and the element's name, count and property names (no columns).
  std::function<void(const PlyData& so_far, const PlyElement& declared)> start;
  /// Each block of rows in order: its columns (`block.count` rows, `block.first_row` the first's index).
  std::function<void(const PlyElement& block)> take;
};

/// Reads a PLY file. Throws fillgs::Error on any malformed or truncated input. A binary file
/// whose elements hold scalar properties only is read from the file in blocks (never whole
/// in memory); each of `sinks` takes its element's rows, which the result then lists
/// without columns.
PlyData read_ply(const std::string& path, const std::vector<PlyElementSink>& sinks = {});

/// The header of a PLY only (up to end_header, at most 1 MiB), to sniff a format cheaply.
std::string read_ply_header(const std::string& path);

/// Writes elements of float properties atomically (temporary file, then rename).
void write_ply(const std::string& path, const PlyData& data);

}  // namespace fillgs
