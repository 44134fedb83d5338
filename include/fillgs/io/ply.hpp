#pragma once
// A small PLY reader and writer (ASCII, binary little- and big-endian).
//
// Scalar properties are read into float columns, looked up by name; list properties
// (faces in mesh files) are parsed and dropped. Errors name the file, the element,
// the record and the property.
#include <cstddef>
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
};

struct PlyData {
  PlyFormat format = PlyFormat::BinaryLittleEndian;
  std::vector<std::string> comments;
  std::vector<PlyElement> elements;
  /// The named element; throws naming the file if it is absent.
  const PlyElement& element(const std::string& name) const;
  const PlyElement* find(const std::string& name) const;
};

/// Reads a PLY file. Throws fillgs::Error on any malformed or truncated input.
PlyData read_ply(const std::string& path);

/// The header of a PLY only (up to end_header, at most 1 MiB), to sniff a format cheaply.
std::string read_ply_header(const std::string& path);

/// Writes elements of float properties atomically (temporary file, then rename).
void write_ply(const std::string& path, const PlyData& data);

}  // namespace fillgs
