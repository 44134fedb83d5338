#include "fillgs/base/json_file.hpp"

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"

namespace fillgs {

nlohmann::json read_json_file(const std::string& path) {
  const std::string text = read_file(path);
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw_error(path, ": invalid JSON (", e.what(), ")");
  }
}

nlohmann::json read_json_object(const std::string& path) {
  nlohmann::json j = read_json_file(path);
  if (!j.is_object()) throw_error(path, ": expected a JSON object, got ", j.is_array() ? "an array" : j.type_name());
  return j;
}

}  // namespace fillgs
