#pragma once
// Reading a JSON file: every JSON reader in fillgs goes through here, so a damaged file is
// reported as "PATH: invalid JSON (...)" and never as a bare library exception (nlohmann
// throws out_of_range, not parse_error, for numbers like 1e911).
#include <string>

#include <nlohmann/json.hpp>

namespace fillgs {

nlohmann::json read_json_file(const std::string& path);
/// A JSON file that must hold an object (a record, a summary, options): "PATH: expected a
/// JSON object, got an array" otherwise.
nlohmann::json read_json_object(const std::string& path);

}  // namespace fillgs
