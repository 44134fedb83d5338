#include "fillgs/base/row_table.hpp"

#include <charconv>
#include <cmath>

namespace fillgs {

namespace {
RowParameter declared(std::string key, RowParameter::Kind kind, std::string default_text, std::string help) {
  RowParameter p;
  p.key = std::move(key);
  p.kind = kind;
  p.default_text = std::move(default_text);
  p.help = std::move(help);
  return p;
}
}  // namespace

RowParameter RowParameter::integer(std::string key, long long default_value, Bounds bounds, std::string help) {
  RowParameter p = declared(std::move(key), Kind::Integer, std::to_string(default_value), std::move(help));
  p.bounds = std::move(bounds);
  return p;
}

RowParameter RowParameter::number(std::string key, double default_value, Bounds bounds, std::string help) {
  // The shortest text that reads back as the same double (number_text keeps 6 digits).
  char text[64];
  const auto end = std::to_chars(text, text + sizeof text, default_value).ptr;
  RowParameter p = declared(std::move(key), Kind::Number, std::string(text, end), std::move(help));
  p.bounds = std::move(bounds);
  return p;
}

RowParameter RowParameter::choice(std::string key, std::string default_value, std::vector<std::string> choices, std::string help) {
  RowParameter p = declared(std::move(key), Kind::Choice, std::move(default_value), std::move(help));
  p.choices = std::move(choices);
  return p;
}

RowParameter RowParameter::text(std::string key, std::string help, bool required) {
  RowParameter p = declared(std::move(key), Kind::Text, "", std::move(help));
  p.required = required;
  return p;
}

std::string RowParameter::problem(const std::string& text, double* number) const {
  if (kind == Kind::Text) return "";
  if (kind == Kind::Choice) {
    if (std::find(choices.begin(), choices.end(), text) != choices.end()) return "";
    return "expects " + join_names(choices) + ", got '" + text.substr(0, 40) + "'";
  }
  double x = 0;
  const std::string why = check_number(text, kind == Kind::Integer, bounds, &x);
  if (why.empty() && number) *number = x;
  return why;
}

void RowParameterValues::set(const RowParameter& p, const std::string& text, const std::string& as) {
  const std::string why = p.problem(text);
  if (!why.empty()) throw_error(as, " ", why);
  values_[p.key] = text;
}

void RowParameterValues::require(const std::vector<const RowParameter*>& parameters, const Spelling& spell) const {
  for (const RowParameter* p : parameters)
    if (p->required && text(*p).empty()) throw_error("missing ", spell(p->key));
}

const std::string& RowParameterValues::text(const RowParameter& p) const {
  const auto it = values_.find(p.key);
  return it == values_.end() ? p.default_text : it->second;
}

double RowParameterValues::number(const RowParameter& p) const {
  double x = 0;
  // A value kept here was checked when set; a declaration's own default is checked by the
  // rows' test. Either way a bad one is refused, not read as 0.
  const std::string why = p.problem(text(p), &x);
  if (!why.empty()) throw_error(p.key, " ", why);
  return x;
}

long long RowParameterValues::integer(const RowParameter& p) const { return static_cast<long long>(std::llround(number(p))); }

nlohmann::json RowParameterValues::identity(const std::vector<const RowParameter*>& parameters) const {
  nlohmann::json j = nlohmann::json::object();
  for (const RowParameter* p : parameters) {
    if (p->kind == RowParameter::Kind::Choice || p->kind == RowParameter::Kind::Text) j[p->key] = text(*p);
    else if (p->kind == RowParameter::Kind::Integer) j[p->key] = integer(*p);
    else j[p->key] = number(*p);
  }
  return j;
}

}  // namespace fillgs
