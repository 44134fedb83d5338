#pragma once
// Tables of rows: model formats (io/model_formats.hpp), refiners (method/refiners.hpp) and
// selection strategies (method/strategies.hpp). Each row is one file in its folder that
// defines `const Row& row_<file name>()`; the build lists the folder's files
// (CMakeLists.txt, fillgs_row_table; src/row_table.cpp.in), and RowTable orders the rows,
// finds one by its name or an alias, and lists their names and their parameters.
//
// A row declares the parameters only it reads (RowParameter: a name, a help line, a default,
// a range or a list of choices). The command line's flags (`--stg-duration`), the Python
// module's keywords (`stg_duration=`) and a run's identity are made from those declarations,
// and the values a face was given reach the row as RowParameterValues, checked once here. So
// a row with a parameter of its own is one file (and its test):
//
//   const RowParameter& duration() {
//     static const RowParameter p = RowParameter::integer("stg_duration", 50, at_least(1), "frames one model covers");
//     return p;
//   }
//   ... row.parameters = {&duration()};  ... options.parameters.integer(duration())
#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fillgs/base/bounds.hpp"
#include "fillgs/base/error.hpp"
#include "fillgs/base/names.hpp"

namespace fillgs {

/// A parameter one row reads: its key (the library's, the Python keyword; the flag is its
/// command-line spelling, base/bounds.hpp Spelling), its help, default and check.
struct RowParameter {
  enum class Kind { Integer, Number, Choice, Text };
  std::string key;
  Kind kind = Kind::Number;
  std::string help;
  std::string default_text;          ///< the default as a face would write it ("50", "auto")
  Bounds bounds;                     ///< Integer and Number
  std::vector<std::string> choices;  ///< Choice: the names it takes
  std::vector<std::string> flag_aliases;  ///< older flags that set it too ("--duration")
  bool required = false;  ///< the row cannot run without it (RowParameterValues::require)

  static RowParameter integer(std::string key, long long default_value, Bounds bounds, std::string help);
  static RowParameter number(std::string key, double default_value, Bounds bounds, std::string help);
  static RowParameter choice(std::string key, std::string default_value, std::vector<std::string> choices, std::string help);
  /// Any text (a command); `required`: no default, a run of its row needs it given.
  static RowParameter text(std::string key, std::string help, bool required);
  /// Why `text` is no value it takes ("must be at least 1, got 0"); empty where it is (the
  /// value, parsed, in *number for Integer and Number).
  std::string problem(const std::string& text, double* number = nullptr) const;
};

/// The values a face gave for rows' parameters, by key; a parameter not given reads as its
/// declared default.
class RowParameterValues {
 public:
  /// Checks `text` against the declaration and keeps it; otherwise throws the one line
  /// "<key as `spell` writes it> must be at least 1, got 0".
  void set(const RowParameter& p, const std::string& text, const Spelling& spell = {}) { set(p, text, spell(p.key)); }
  /// The same, the parameter named `as` in the message (a flag as the user typed it).
  void set(const RowParameter& p, const std::string& text, const std::string& as);
  bool given(const RowParameter& p) const { return values_.count(p.key) > 0; }
  /// Throws "missing <key as `spell` writes it>" for each of `parameters` that is required
  /// and was not given (or given empty).
  void require(const std::vector<const RowParameter*>& parameters, const Spelling& spell = {}) const;
  long long integer(const RowParameter& p) const;
  double number(const RowParameter& p) const;
  const std::string& text(const RowParameter& p) const;
  /// Every parameter's value (given or default), by key: what of them a run's identity holds.
  nlohmann::json identity(const std::vector<const RowParameter*>& parameters) const;

 private:
  std::map<std::string, std::string> values_;
};

/// The fields every row has: how the faces name it, one line about it, where it is listed,
/// and the parameters only it reads.
struct RowHeading {
  std::string name;
  std::vector<std::string> aliases;  ///< other names that parse to it
  std::string description;           ///< one line (help, reports)
  int order = 50;                    ///< listing order, lower first
  std::vector<const RowParameter*> parameters;
};

/// A kind of row's table: `what` names the kind in messages ("refiner"), `rows` the build's
/// list; the rows ordered by `order` (ties by file name).
template <class Row>
class RowTable {
 public:
  RowTable(std::string what, std::vector<const Row*> rows, std::vector<std::string> also_accepted = {})
      : what_(std::move(what)), rows_(std::move(rows)), also_(std::move(also_accepted)) {
    std::stable_sort(rows_.begin(), rows_.end(), [](const Row* a, const Row* b) { return a->order < b->order; });
  }
  const std::vector<const Row*>& rows() const { return rows_; }
  /// The row of that name or alias; null when none.
  const Row* lookup(const std::string& name) const {
    for (const Row* r : rows_) {
      if (r->name == name) return r;
      for (const std::string& a : r->aliases)
        if (a == name) return r;
    }
    return nullptr;
  }
  /// The row of that name or alias; otherwise "unknown <what> 'x' (expected a, b or c)".
  const Row& find(const std::string& name) const {
    if (const Row* r = lookup(name)) return *r;
    throw_error("unknown ", what_, " '", name.substr(0, 40), "' (expected ", names(), ")");
  }
  /// "a, b or c": the names the faces take (with the table's also-accepted words first).
  std::string names() const {
    std::vector<std::string> n = also_;
    for (const Row* r : rows_) n.push_back(r->name);
    return join_names(n);
  }
  /// Every row's parameters, each key once, in the rows' order.
  std::vector<const RowParameter*> parameters() const {
    std::vector<const RowParameter*> out;
    for (const Row* r : rows_)
      for (const RowParameter* p : r->parameters)
        if (std::none_of(out.begin(), out.end(), [&](const RowParameter* q) { return q->key == p->key; })) out.push_back(p);
    return out;
  }
  /// The parameter of that key among every row's; null when none.
  const RowParameter* parameter(const std::string& key) const {
    for (const RowParameter* p : parameters())
      if (p->key == key) return p;
    return nullptr;
  }

 private:
  std::string what_;
  std::vector<const Row*> rows_;
  std::vector<std::string> also_;
};

}  // namespace fillgs
