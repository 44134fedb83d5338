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

}  // namespace fillgs
