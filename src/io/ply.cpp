#include "fillgs/io/ply.hpp"

#include <fstream>
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <sstream>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"

namespace fillgs {

namespace {

enum class Type { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

bool parse_type(const std::string& s, Type* t) {
  static const struct { const char* name; Type type; } table[] = {
      {"char", Type::Int8},     {"int8", Type::Int8},     {"uchar", Type::UInt8},   {"uint8", Type::UInt8},
      {"short", Type::Int16},   {"int16", Type::Int16},   {"ushort", Type::UInt16}, {"uint16", Type::UInt16},
      {"int", Type::Int32},     {"int32", Type::Int32},   {"uint", Type::UInt32},   {"uint32", Type::UInt32},
      {"float", Type::Float32}, {"float32", Type::Float32}, {"double", Type::Float64}, {"float64", Type::Float64}};
  for (const auto& e : table)
    if (s == e.name) {
      *t = e.type;
      return true;
    }
  return false;
}

size_t type_size(Type t) {
  switch (t) {
    case Type::Int8: case Type::UInt8: return 1;
    case Type::Int16: case Type::UInt16: return 2;
    case Type::Int32: case Type::UInt32: case Type::Float32: return 4;
    case Type::Float64: return 8;
  }
  return 0;
}

struct PropertyDecl {
  std::string name;
  Type type = Type::Float32;
  bool is_list = false;
  Type count_type = Type::UInt8;
};

struct ElementDecl {
  std::string name;
  size_t count = 0;
  std::vector<PropertyDecl> properties;
};

double load_binary(const unsigned char* p, Type t, bool swap) {
  unsigned char b[8];
  const size_t n = type_size(t);
  if (swap)
    for (size_t i = 0; i < n; ++i) b[i] = p[n - 1 - i];
  else
    std::memcpy(b, p, n);
  switch (t) {
    case Type::Int8: { int8_t v; std::memcpy(&v, b, 1); return v; }
    case Type::UInt8: { uint8_t v; std::memcpy(&v, b, 1); return v; }
    case Type::Int16: { int16_t v; std::memcpy(&v, b, 2); return v; }
    case Type::UInt16: { uint16_t v; std::memcpy(&v, b, 2); return v; }
    case Type::Int32: { int32_t v; std::memcpy(&v, b, 4); return v; }
    case Type::UInt32: { uint32_t v; std::memcpy(&v, b, 4); return v; }
    case Type::Float32: { float v; std::memcpy(&v, b, 4); return v; }
    case Type::Float64: { double v; std::memcpy(&v, b, 8); return v; }
  }
  return 0;
}

bool host_is_little_endian() {
  const uint16_t one = 1;
  unsigned char c;
  std::memcpy(&c, &one, 1);
  return c == 1;
}

}  // namespace

bool PlyElement::has(const std::string& property) const {
  return std::find(property_names.begin(), property_names.end(), property) != property_names.end();
}

const std::vector<float>& PlyElement::column(const std::string& property) const {
  auto it = std::find(property_names.begin(), property_names.end(), property);
  if (it == property_names.end())
    throw_error(source, ": property '", property, "' missing (", name, " element has ", property_names.size(),
                " properties)");
  if (columns.size() != property_names.size()) throw_error(source, ": element '", name, "' was read in blocks by its reader; its columns are not kept");
  return columns[size_t(it - property_names.begin())];
}

const std::vector<float>& PlyElement::finite_column(const std::string& property) const {
  const std::vector<float>& c = column(property);
  for (size_t i = 0; i < c.size(); ++i)
    if (!std::isfinite(c[i]))
      throw_error(source, ": ", name, " ", first_row + i, " property '", property, "' is ",
                  std::isnan(c[i]) ? "NaN" : "infinite");
  return c;
}

std::vector<std::string> PlyElement::indexed_properties(const std::string& prefix) const {
  std::vector<std::pair<long, std::string>> found;
  for (const std::string& n : property_names) {
    if (n.size() <= prefix.size() || n.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string rest = n.substr(prefix.size());
    if (rest.find_first_not_of("0123456789") != std::string::npos) continue;
    found.emplace_back(std::strtol(rest.c_str(), nullptr, 10), n);
  }
  std::sort(found.begin(), found.end());
  std::vector<std::string> names;
  for (size_t i = 0; i < found.size(); ++i) {
    if (found[i].first != long(i))
      throw_error(source, ": properties '", prefix, "*' are not numbered 0..", found.size() - 1, " (",
                  prefix, i, " missing)");
    names.push_back(found[i].second);
  }
  return names;
}

const PlyElement* PlyData::find(const std::string& name) const {
  for (const PlyElement& e : elements)
    if (e.name == name) return &e;
  return nullptr;
}

const PlyElement& PlyData::element(const std::string& name) const {
  const PlyElement* e = find(name);
  if (!e) throw_error(elements.empty() ? "PLY" : elements[0].source, ": no '", name, "' element");
  return *e;
}

namespace {

/// The bytes of a PLY up to and including its end_header line, read in pieces (the whole
/// file when it has none within 64 MiB: the header's own checks then say what is wrong).
std::string read_head(const std::string& path) {
  require_regular_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_error(path, ": cannot open (", std::strerror(errno), ")");
  std::string head;
  char piece[65536];
  while (head.size() < (size_t(64) << 20)) {
    in.read(piece, sizeof piece);
    const size_t got = size_t(in.gcount());
    if (got == 0) break;
    const size_t from = head.size() > 16 ? head.size() - 16 : 0;
    head.append(piece, got);
    const size_t at = head.find("end_header", from);
    if (at != std::string::npos && (at == 0 || head[at - 1] == '\n')) {
      const size_t eol = head.find('\n', at);
      if (eol != std::string::npos) return head.substr(0, eol + 1);
    }
  }
  return head;
}

}  // namespace

PlyData read_ply(const std::string& path, const std::vector<PlyElementSink>& sinks) {
  std::string bytes = read_head(path);
  // ---- header ----
  if (bytes.compare(0, 3, "ply") != 0 || bytes.size() < 4 || (bytes[3] != '\n' && bytes[3] != '\r'))
    throw_error(path, ": not a PLY file (missing 'ply' magic line)");
  size_t pos = 0;
  auto next_line = [&](std::string* line) -> bool {
    if (pos >= bytes.size()) return false;
    size_t e = bytes.find('\n', pos);
    if (e == std::string::npos) return false;
    *line = bytes.substr(pos, e - pos);
    if (!line->empty() && line->back() == '\r') line->pop_back();
    pos = e + 1;
    return true;
  };
  PlyData data;
  std::vector<ElementDecl> decls;
  std::string line;
  next_line(&line);  // "ply"
  bool have_format = false, have_end = false;
  int line_no = 1;
  while (next_line(&line)) {
    ++line_no;
    std::istringstream ls(line);
    std::string kw;
    ls >> kw;
    if (kw.empty()) continue;
    if (kw == "format") {
      std::string f, v;
      ls >> f >> v;
      if (f == "ascii") data.format = PlyFormat::Ascii;
      else if (f == "binary_little_endian") data.format = PlyFormat::BinaryLittleEndian;
      else if (f == "binary_big_endian") data.format = PlyFormat::BinaryBigEndian;
      else throw_error(path, ": header line ", line_no, ": unknown format '", f, "'");
      have_format = true;
    } else if (kw == "comment" || kw == "obj_info") {
      data.comments.push_back(line.size() > kw.size() + 1 ? line.substr(kw.size() + 1) : "");
    } else if (kw == "element") {
      ElementDecl e;
      long long count = -1;
      ls >> e.name >> count;
      if (e.name.empty() || count < 0 || ls.fail())
        throw_error(path, ": header line ", line_no, ": malformed element line '", line, "'");
      e.count = size_t(count);
      decls.push_back(e);
    } else if (kw == "property") {
      if (decls.empty()) throw_error(path, ": header line ", line_no, ": property before any element");
      PropertyDecl p;
      std::string t;
      ls >> t;
      if (t == "list") {
        std::string ct, it;
        ls >> ct >> it >> p.name;
        if (!parse_type(ct, &p.count_type) || !parse_type(it, &p.type))
          throw_error(path, ": header line ", line_no, ": unknown list types in '", line, "'");
        p.is_list = true;
      } else {
        if (!parse_type(t, &p.type)) throw_error(path, ": header line ", line_no, ": unknown type '", t, "'");
        ls >> p.name;
      }
      if (p.name.empty()) throw_error(path, ": header line ", line_no, ": property without a name");
      for (const PropertyDecl& q : decls.back().properties)
        if (q.name == p.name)
          throw_error(path, ": header line ", line_no, ": element '", decls.back().name, "' declares property '", p.name, "' twice");
      decls.back().properties.push_back(p);
    } else if (kw == "end_header") {
      have_end = true;
      break;
    } else {
      throw_error(path, ": header line ", line_no, ": unknown keyword '", kw, "'");
    }
  }
  if (!have_end) throw_error(path, ": header has no end_header (truncated?)");
  if (!have_format) throw_error(path, ": header has no format line");

  // ---- body ----
  const bool binary = data.format != PlyFormat::Ascii;
  // Binary elements of scalars only are read from the file a block of rows at a time; any
  // other body is read whole (its header is the first bytes read again).
  const bool streamed = binary && std::all_of(decls.begin(), decls.end(), [](const ElementDecl& d) {
    return std::none_of(d.properties.begin(), d.properties.end(), [](const PropertyDecl& p) { return p.is_list; });
  });
  std::unique_ptr<FILE, int (*)(FILE*)> file(nullptr, &std::fclose);
  size_t file_size = 0;
  if (streamed) {
    std::error_code ec;
    file_size = size_t(std::filesystem::file_size(path, ec));
    if (ec) throw_error(path, ": cannot read its size (", ec.message(), ")");
    file.reset(std::fopen(path.c_str(), "rb"));
    if (!file || std::fseek(file.get(), long(pos), SEEK_SET) != 0) throw_error(path, ": cannot open (", std::strerror(errno), ")");
  } else {
    bytes = read_file(path);
  }
  const bool swap = binary && ((data.format == PlyFormat::BinaryLittleEndian) != host_is_little_endian());
  const unsigned char* base = reinterpret_cast<const unsigned char*>(bytes.data());
  const size_t end = streamed ? file_size : bytes.size();
  // ASCII: a token cursor over the whole body.
  const char* cur = bytes.c_str() + pos;
  const char* stop = bytes.c_str() + end;
  auto next_token = [&](double* v) -> bool {
    while (cur < stop && std::isspace(static_cast<unsigned char>(*cur))) ++cur;
    if (cur >= stop) return false;
    char* e = nullptr;
    *v = std::strtod(cur, &e);
    if (e == cur) return false;
    cur = e;
    return true;
  };

  for (const ElementDecl& d : decls) {
    PlyElement el;
    el.name = d.name;
    el.count = d.count;
    el.source = path;
    std::vector<int> column_of(d.properties.size(), -1);
    for (size_t i = 0; i < d.properties.size(); ++i) {
      if (d.properties[i].is_list) continue;
      column_of[i] = int(el.property_names.size());
      el.property_names.push_back(d.properties[i].name);
    }
    // The count is the file's word: check it against the bytes left before taking memory.
    // A binary record is at least its scalars plus its list lengths; an ASCII one at least
    // one character and one separator per value.
    if (d.count > 0 && d.properties.empty())
      throw_error(path, ": element '", d.name, "' has ", d.count, " records but no properties");
    size_t min_record = 0;
    for (const PropertyDecl& p : d.properties) min_record += binary ? type_size(p.is_list ? p.count_type : p.type) : 2;
    if (d.count > (end - pos + 1) / std::max<size_t>(min_record, 1))
      throw_error(path, ": truncated or corrupt: element '", d.name, "' claims ", d.count, " records of at least ", min_record, " bytes, but only ",
                  end - pos, " bytes follow");
    const PlyElementSink* sink = nullptr;
    for (const PlyElementSink& k : sinks)
      if (k.element == d.name) sink = &k;
    const bool sunk = sink != nullptr;
    if (sunk) sink->start(data, el);
    bool all_scalar = std::all_of(d.properties.begin(), d.properties.end(), [](const PropertyDecl& p) { return !p.is_list; });
    if (!(binary && all_scalar)) el.columns.assign(el.property_names.size(), std::vector<float>(d.count));
    if (binary && all_scalar) {
      size_t record = 0;
      for (const auto& p : d.properties) record += type_size(p.type);
      const size_t need = record * d.count;
      if (end - pos < need)
        throw_error(path, ": truncated: element '", d.name, "' needs ", d.count, " records of ", record, " bytes (",
                    need, " bytes) but only ", end - pos, " bytes follow the header");
      // Fast path for the common all-float32 native-endian case.
      const bool all_native_float =
          !swap && std::all_of(d.properties.begin(), d.properties.end(), [](const PropertyDecl& p) { return p.type == Type::Float32; });
      const size_t np = d.properties.size();
      // Rows `n` records at `src` into `cols` from row `at`.
      auto convert = [&](const unsigned char* src, size_t n, std::vector<std::vector<float>>& cols, size_t at) {
        if (all_native_float) {
          for (size_t r = 0; r < n; ++r)
            for (size_t i = 0; i < np; ++i) std::memcpy(&cols[i][at + r], src + r * record + 4 * i, 4);
          return;
        }
        for (size_t r = 0; r < n; ++r) {
          size_t off = 0;
          for (size_t i = 0; i < np; ++i) {
            cols[size_t(column_of[i])][at + r] = float(load_binary(src + r * record + off, d.properties[i].type, swap));
            off += type_size(d.properties[i].type);
          }
        }
      };
      // A block of about 1 MiB of records at a time: read from the file (streamed) and, for
      // the sink's element, handed over as a block instead of kept.
      const size_t rows_per_block = std::max<size_t>(1, (size_t(1) << 20) / std::max<size_t>(record, 1));
      std::vector<unsigned char> buffer(streamed ? std::min(d.count, rows_per_block) * record : 0);
      PlyElement block;
      if (sunk) {
        block.name = el.name, block.source = path, block.property_names = el.property_names;
        block.columns.assign(np, std::vector<float>(std::min(d.count, rows_per_block)));
      } else {
        el.columns.assign(el.property_names.size(), std::vector<float>(d.count));
      }
      for (size_t r0 = 0; r0 < d.count; r0 += rows_per_block) {
        const size_t n = std::min(rows_per_block, d.count - r0);
        const unsigned char* src = base + pos + r0 * record;
        if (streamed) {
          if (std::fread(buffer.data(), record, n, file.get()) != n)
            throw_error(path, ": truncated while reading element '", d.name, "' row ", r0, " (the file changed while it was read?)");
          src = buffer.data();
        }
        if (!sunk) {
          convert(src, n, el.columns, r0);
          continue;
        }
        for (auto& c : block.columns) c.resize(n);
        convert(src, n, block.columns, 0);
        block.count = n;
        block.first_row = r0;
        sink->take(block);
      }
      pos += need;
    } else if (binary) {
      for (size_t r = 0; r < d.count; ++r) {
        for (size_t i = 0; i < d.properties.size(); ++i) {
          const PropertyDecl& p = d.properties[i];
          if (p.is_list) {
            if (end - pos < type_size(p.count_type))
              throw_error(path, ": truncated in ", d.name, " ", r, " property '", p.name, "'");
            const double n = load_binary(base + pos, p.count_type, swap);
            pos += type_size(p.count_type);
            if (n < 0) throw_error(path, ": ", d.name, " ", r, " property '", p.name, "' has a negative list length");
            const size_t bytes_needed = size_t(n) * type_size(p.type);
            if (end - pos < bytes_needed) throw_error(path, ": truncated in ", d.name, " ", r, " property '", p.name, "'");
            pos += bytes_needed;
          } else {
            if (end - pos < type_size(p.type))
              throw_error(path, ": truncated in ", d.name, " ", r, " property '", p.name, "'");
            el.columns[size_t(column_of[i])][r] = float(load_binary(base + pos, p.type, swap));
            pos += type_size(p.type);
          }
        }
      }
    } else {
      for (size_t r = 0; r < d.count; ++r) {
        for (size_t i = 0; i < d.properties.size(); ++i) {
          const PropertyDecl& p = d.properties[i];
          double v = 0;
          if (!next_token(&v))
            throw_error(path, ": truncated or malformed at ", d.name, " ", r, " property '", p.name, "'");
          if (p.is_list) {
            if (v < 0) throw_error(path, ": ", d.name, " ", r, " property '", p.name, "' has a negative list length");
            for (long k = 0; k < long(v); ++k) {
              double dummy;
              if (!next_token(&dummy)) throw_error(path, ": truncated in ", d.name, " ", r, " property '", p.name, "'");
            }
          } else {
            el.columns[size_t(column_of[i])][r] = float(v);
          }
        }
      }
    }
    if (sunk && !(binary && all_scalar)) {  // parsed whole: handed over as one block
      sink->take(el);
      el.columns.clear();
    }
    data.elements.push_back(std::move(el));
  }
  if (binary && pos != end)
    throw_error(path, ": ", end - pos, " bytes follow the last element (a wrong count, or a body that is not ",
                data.format == PlyFormat::BinaryLittleEndian ? "binary_little_endian" : "binary_big_endian", ")");
  if (!binary) {
    while (cur < stop && std::isspace(static_cast<unsigned char>(*cur))) ++cur;
    if (cur < stop) throw_error(path, ": values follow the last element (", stop - cur, " bytes; a wrong count?)");
  }
  return data;
}

namespace {

void append_float(std::string& out, float v, bool big_endian) {
  unsigned char b[4];
  std::memcpy(b, &v, 4);
  if (big_endian == host_is_little_endian()) std::reverse(b, b + 4);
  out.append(reinterpret_cast<const char*>(b), 4);
}

}  // namespace

void write_ply(const std::string& path, const PlyData& data) {
  std::ostringstream h;
  h << "ply\nformat "
    << (data.format == PlyFormat::Ascii ? "ascii" : data.format == PlyFormat::BinaryLittleEndian ? "binary_little_endian" : "binary_big_endian")
    << " 1.0\n";
  for (const std::string& c : data.comments) h << "comment " << c << "\n";
  for (const PlyElement& e : data.elements) {
    FILLGS_CHECK_EQ(e.columns.size(), e.property_names.size());
    h << "element " << e.name << " " << e.count << "\n";
    for (const std::string& n : e.property_names) h << "property float " << n << "\n";
  }
  h << "end_header\n";
  std::string out = h.str();
  for (const PlyElement& e : data.elements) {
    for (const auto& c : e.columns) FILLGS_CHECK_EQ(c.size(), e.count);
    if (data.format == PlyFormat::Ascii) {
      std::ostringstream body;
      body.precision(9);
      for (size_t r = 0; r < e.count; ++r) {
        for (size_t i = 0; i < e.columns.size(); ++i) body << (i ? " " : "") << e.columns[i][r];
        body << "\n";
      }
      out += body.str();
    } else {
      const bool be = data.format == PlyFormat::BinaryBigEndian;
      out.reserve(out.size() + e.count * e.columns.size() * 4);
      for (size_t r = 0; r < e.count; ++r)
        for (const auto& c : e.columns) append_float(out, c[r], be);
    }
  }
  write_file_atomically(path, out);
}

std::string read_ply_header(const std::string& path) {
  require_regular_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_error(path, ": cannot open");
  std::string header, line;
  while (std::getline(in, line)) {
    header += line + "\n";
    if (line.rfind("end_header", 0) == 0 || header.size() > (1 << 20)) break;
  }
  return header;
}

}  // namespace fillgs
