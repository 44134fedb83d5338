#include "fillgs/io/npy.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <unistd.h>
#include <sstream>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/limits.hpp"

namespace fillgs {

size_t NpyArray::size() const {
  size_t n = 1;
  for (size_t d : shape) n *= d;
  return n;
}

template <> const char* npy_descr<float>() { return "<f4"; }
template <> const char* npy_descr<double>() { return "<f8"; }
template <> const char* npy_descr<uint8_t>() { return "|u1"; }
template <> const char* npy_descr<uint16_t>() { return "<u2"; }
template <> const char* npy_descr<uint32_t>() { return "<u4"; }
template <> const char* npy_descr<int32_t>() { return "<i4"; }
template <> const char* npy_descr<int64_t>() { return "<i8"; }

NpyArray read_npy(const std::string& path) { return parse_npy(read_file(path), path); }

NpyArray parse_npy(const std::string& b, const std::string& path) {
  if (b.size() < 10 || b.compare(0, 6, "\x93NUMPY") != 0) throw_error(path, ": not a .npy file (bad magic)");
  const int major = static_cast<unsigned char>(b[6]);
  size_t header_len = 0, offset = 0;
  if (major == 1) {
    header_len = size_t(static_cast<unsigned char>(b[8])) | (size_t(static_cast<unsigned char>(b[9])) << 8);
    offset = 10;
  } else if (major == 2 || major == 3) {
    if (b.size() < 12) throw_error(path, ": truncated .npy header");
    header_len = 0;
    for (int i = 0; i < 4; ++i) header_len |= size_t(static_cast<unsigned char>(b[8 + i])) << (8 * i);
    offset = 12;
  } else {
    throw_error(path, ": unsupported .npy version ", major);
  }
  if (b.size() < offset + header_len) throw_error(path, ": truncated .npy header");
  const std::string header = b.substr(offset, header_len);
  NpyArray a;
  // The header is a Python dict literal; it is scanned by hand (no regex: a long header
  // must not cost stack) and every value is checked exactly.
  auto value_of = [&](const char* key) -> size_t {
    const std::string quoted = std::string("'") + key + "'";
    size_t at = header.find(quoted);
    if (at == std::string::npos) throw_error(path, ": .npy header has no ", key);
    at += quoted.size();
    while (at < header.size() && header[at] == ' ') ++at;
    if (at >= header.size() || header[at] != ':') throw_error(path, ": .npy header: no ':' after ", key);
    ++at;
    while (at < header.size() && header[at] == ' ') ++at;
    return at;
  };
  {
    const size_t at = value_of("descr");
    const size_t close = at < header.size() && header[at] == '\'' ? header.find('\'', at + 1) : std::string::npos;
    if (close == std::string::npos) throw_error(path, ": .npy header: descr is not a quoted string");
    a.descr = header.substr(at + 1, close - at - 1);
  }
  {
    const size_t at = value_of("fortran_order");
    if (header.compare(at, 4, "True") == 0) a.fortran_order = true;
    else if (header.compare(at, 5, "False") == 0) a.fortran_order = false;
    else throw_error(path, ": .npy header: fortran_order is neither True nor False");
  }
  {
    const size_t at = value_of("shape");
    const size_t close = at < header.size() && header[at] == '(' ? header.find(')', at) : std::string::npos;
    if (close == std::string::npos) throw_error(path, ": .npy header: shape is not a tuple");
    std::string dims = header.substr(at + 1, close - at - 1);
    size_t from = 0;
    while (from <= dims.size()) {
      size_t comma = dims.find(',', from);
      if (comma == std::string::npos) comma = dims.size();
      const std::string tok = dims.substr(from, comma - from);
      if (tok.find_first_not_of(" ") != std::string::npos)
        a.shape.push_back(parse_count(tok, size_t(1) << 48, path, ".npy shape dimension " + std::to_string(a.shape.size())));
      from = comma + 1;
    }
  }
  static const char* const kKnown[] = {"<f4", "<f8", "<i4", "<i8", "|u1", "<u1", "<u2", "<u4"};
  bool known = false;
  for (const char* k : kKnown) known = known || a.descr == k;
  if (!known) throw_error(path, ": unsupported .npy dtype '", a.descr.substr(0, 40), "' (fillgs reads <f4 <f8 <i4 <i8 |u1 <u2 <u4)");
  const size_t item = size_t(a.descr[2] - '0');
  size_t count = 1;
  for (size_t d : a.shape) count = checked_mul(count, d, path, ".npy shape");
  const size_t need = checked_mul(count, item, path, ".npy data size");
  const size_t data_at = offset + header_len;
  if (b.size() - data_at < need)
    throw_error(path, ": truncated: shape needs ", need, " bytes of data, file has ", b.size() - data_at);
  a.bytes = b.substr(data_at, need);
  return a;
}

std::vector<double> NpyArray::to_doubles(const std::string& source) const {
  const char order = descr[0];
  const char kind = descr[1];
  const size_t item = size_t(std::atoi(descr.c_str() + 2));
  if (order == '>') throw_error(source, ": big-endian .npy arrays are not supported");
  const size_t n = size();
  std::vector<double> out(n);
  for (size_t i = 0; i < n; ++i) {
    const char* p = bytes.data() + i * item;
    double v = 0;
    if (kind == 'f' && item == 4) { float f; std::memcpy(&f, p, 4); v = f; }
    else if (kind == 'f' && item == 8) { std::memcpy(&v, p, 8); }
    else if (kind == 'i' && item == 4) { int32_t x; std::memcpy(&x, p, 4); v = x; }
    else if (kind == 'i' && item == 8) { int64_t x; std::memcpy(&x, p, 8); v = double(x); }
    else if (kind == 'u' && item == 1) { v = static_cast<unsigned char>(*p); }
    else if (kind == 'u' && item == 2) { uint16_t x; std::memcpy(&x, p, 2); v = x; }
    else if (kind == 'u' && item == 4) { uint32_t x; std::memcpy(&x, p, 4); v = x; }
    else throw_error(source, ": unsupported .npy dtype '", descr, "'");
    out[i] = v;
  }
  if (fortran_order && shape.size() == 2 && n > 0) {  // n = 0: nothing to transpose, whatever the other side claims
    std::vector<double> c(n);
    const size_t R = shape[0], C = shape[1];
    for (size_t r = 0; r < R; ++r)
      for (size_t k = 0; k < C; ++k) c[r * C + k] = out[k * R + r];
    return c;
  }
  if (fortran_order && shape.size() > 2) throw_error(source, ": Fortran-order arrays of rank > 2 are not supported");
  return out;
}

std::string npy_header(const std::string& descr, const std::vector<size_t>& shape, size_t length) {
  std::ostringstream h;
  h << "{'descr': '" << descr << "', 'fortran_order': False, 'shape': (";
  for (size_t i = 0; i < shape.size(); ++i) h << shape[i] << (shape.size() == 1 ? "," : (i + 1 < shape.size() ? ", " : ""));
  h << "), }";
  std::string header = h.str();
  const size_t total = 10 + header.size() + 1;
  FILLGS_CHECK(length == 0 || length >= total);
  header.append(length ? length - total : (64 - total % 64) % 64, ' ');
  header += '\n';
  std::string out = "\x93NUMPY";
  out += char(1);
  out += char(0);
  out += char(header.size() & 0xff);
  out += char((header.size() >> 8) & 0xff);
  out += header;
  return out;
}

template <typename T>
void write_npy(const std::string& path, const T* data, const std::vector<size_t>& shape) {
  size_t n = 1;
  for (size_t d : shape) n *= d;
  std::string out = npy_header(npy_descr<T>(), shape);
  out.append(reinterpret_cast<const char*>(data), n * sizeof(T));
  write_file_atomically(path, out);
}

namespace {

/// Opens the temporary beside `path` and writes `header` into it.
void* open_npy_temporary(const std::string& path, const std::string& tmp, const std::string& header) {
  const size_t slash = path.find_last_of('/');
  if (slash != std::string::npos && slash > 0) make_directories(path.substr(0, slash));
  FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw_error(path, ": cannot open for writing (", std::strerror(errno), ")");
  if (std::fwrite(header.data(), 1, header.size(), f) != header.size()) {
    std::fclose(f);
    std::remove(tmp.c_str());
    throw_error(path, ": write failed");
  }
  return f;
}

}  // namespace

NpyStreamWriter::NpyStreamWriter(const std::string& path, const std::string& descr, size_t item_bytes, const std::vector<size_t>& shape)
    : path_(path), tmp_(path + ".tmp" + std::to_string(::getpid())), descr_(descr) {
  expected_ = item_bytes;
  for (size_t d : shape) expected_ *= d;
  file_ = open_npy_temporary(path_, tmp_, npy_header(descr, shape));
}

NpyStreamWriter NpyStreamWriter::growing(const std::string& path, const std::string& descr, size_t item_bytes, const std::vector<size_t>& row_shape) {
  NpyStreamWriter w;
  w.path_ = path;
  w.tmp_ = path + ".tmp" + std::to_string(::getpid());
  w.descr_ = descr;
  w.row_shape_ = row_shape;
  w.row_bytes_ = item_bytes;
  for (size_t d : row_shape) w.row_bytes_ *= d;
  std::vector<size_t> widest = {std::numeric_limits<size_t>::max()};
  widest.insert(widest.end(), row_shape.begin(), row_shape.end());
  const std::string header = npy_header(descr, widest);
  w.header_bytes_ = header.size();
  w.expected_ = std::numeric_limits<size_t>::max();
  w.file_ = open_npy_temporary(path, w.tmp_, header);
  return w;
}

NpyStreamWriter::NpyStreamWriter(NpyStreamWriter&& o) noexcept
    : path_(std::move(o.path_)), tmp_(std::move(o.tmp_)), descr_(std::move(o.descr_)), file_(o.file_), expected_(o.expected_),
      written_(o.written_), row_bytes_(o.row_bytes_), header_bytes_(o.header_bytes_), row_shape_(std::move(o.row_shape_)) {
  o.file_ = nullptr;
}

NpyStreamWriter::~NpyStreamWriter() {
  if (file_) {
    std::fclose(static_cast<FILE*>(file_));
    std::remove(tmp_.c_str());
  }
}

void NpyStreamWriter::write(const void* data, size_t bytes) {
  FILLGS_CHECK(file_ != nullptr);
  if (bytes > expected_ - written_) throw_error(path_, ": more data than the shape holds");
  if (bytes && std::fwrite(data, 1, bytes, static_cast<FILE*>(file_)) != bytes) throw_error(path_, ": write failed (", std::strerror(errno), ")");
  written_ += bytes;
}

void NpyStreamWriter::finish() {
  FILLGS_CHECK(file_ != nullptr);
  FILE* f = static_cast<FILE*>(file_);
  bool ok = true;
  if (header_bytes_) {  // growing: the row count goes into the reserved header
    const size_t rows = row_bytes_ ? written_ / row_bytes_ : 0;
    if (row_bytes_ ? written_ % row_bytes_ != 0 : written_ != 0)
      throw_error(path_, ": ", written_, " bytes written, not whole rows of ", row_bytes_);
    std::vector<size_t> shape = {rows};
    shape.insert(shape.end(), row_shape_.begin(), row_shape_.end());
    const std::string header = npy_header(descr_, shape, header_bytes_);
    ok = std::fflush(f) == 0 && std::fseek(f, 0, SEEK_SET) == 0 && std::fwrite(header.data(), 1, header.size(), f) == header.size();
  } else if (written_ != expected_) {
    throw_error(path_, ": ", written_, " bytes written, the shape needs ", expected_);
  }
  file_ = nullptr;
  ok = std::fflush(f) == 0 && ok;
  if (std::fclose(f) != 0) ok = false;
  if (!ok || std::rename(tmp_.c_str(), path_.c_str()) != 0) {
    std::remove(tmp_.c_str());
    throw_error(path_, ": cannot finish writing (", std::strerror(errno), ")");
  }
}

template void write_npy<float>(const std::string&, const float*, const std::vector<size_t>&);
template void write_npy<double>(const std::string&, const double*, const std::vector<size_t>&);
template void write_npy<uint8_t>(const std::string&, const uint8_t*, const std::vector<size_t>&);
template void write_npy<uint16_t>(const std::string&, const uint16_t*, const std::vector<size_t>&);
template void write_npy<uint32_t>(const std::string&, const uint32_t*, const std::vector<size_t>&);
template void write_npy<int32_t>(const std::string&, const int32_t*, const std::vector<size_t>&);
template void write_npy<int64_t>(const std::string&, const int64_t*, const std::vector<size_t>&);

}  // namespace fillgs
