#pragma once
// The names of an enum's values: one table per enum, declared beside it. Printing
// (to_string), parsing (parse_name), the command line's choices and their help all read
// that table, so a value gains or changes its name in one place.
//
//   FILLGS_ENUM_NAMES(VisibilityMode, "visibility mode",
//       {VisibilityMode::Frustum, "frustum"}, {VisibilityMode::Raytraced, "raytraced"}, ...);
//
// (in namespace fillgs) specialises EnumNames<VisibilityMode>: `what` names the kind for
// messages, `table` the values. A value's first entry is its name; later entries for the
// same value are aliases that parse but are never printed.
#include <string>
#include <type_traits>
#include <vector>

#include "fillgs/base/error.hpp"

namespace fillgs {

template <class E>
struct NameOf {
  E value;
  const char* name;
};

/// Specialised beside each named enum (FILLGS_ENUM_NAMES): `what` (for messages) and `table`.
template <class E>
struct EnumNames;

#define FILLGS_ENUM_NAMES(Enum, What, ...)                 \
  template <>                                              \
  struct EnumNames<Enum> {                                 \
    static constexpr const char* what = What;              \
    static constexpr NameOf<Enum> table[] = {__VA_ARGS__}; \
  }

template <class E, class = void>
struct HasNames : std::false_type {};
template <class E>
struct HasNames<E, std::void_t<decltype(EnumNames<E>::table)>> : std::true_type {};

/// The value's name ("?" for a value the table lacks, which a test rules out).
template <class E, std::enable_if_t<HasNames<E>::value, int> = 0>
const char* to_string(E value) {
  for (const NameOf<E>& n : EnumNames<E>::table)
    if (n.value == value) return n.name;
  return "?";
}

/// Every value's name, in table order, aliases left out.
template <class E>
std::vector<std::string> names_of() {
  std::vector<std::string> out;
  for (const NameOf<E>& n : EnumNames<E>::table)
    if (std::string(to_string(n.value)) == n.name) out.push_back(n.name);
  return out;
}

/// Every value, in table order, each once.
template <class E>
std::vector<E> values_of() {
  std::vector<E> out;
  for (const NameOf<E>& n : EnumNames<E>::table)
    if (std::string(to_string(n.value)) == n.name) out.push_back(n.value);
  return out;
}

/// "a, b or c": names for a message or a help line.
inline std::string join_names(const std::vector<std::string>& names) {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
  return out;
}

/// "a, b or c": the enum's names for a message.
template <class E>
std::string name_list() {
  return join_names(names_of<E>());
}

/// The value named `name` (aliases included); otherwise an Error
/// "unknown <what> 'x' (expected a, b or c)".
template <class E>
E parse_name(const std::string& name) {
  for (const NameOf<E>& n : EnumNames<E>::table)
    if (name == n.name) return n.value;
  throw_error("unknown ", EnumNames<E>::what, " '", name, "' (expected ", name_list<E>(), ")");
}

}  // namespace fillgs
