#include "fillgs/npy.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <unistd.h>
#include <regex>
#include <sstream>

#include "fillgs/error.hpp"
#include "fillgs/fs_util.hpp"

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

NpyArray read_npy(const std::string& path) {
  const std::string b = read_file(path);
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
  std::smatch m;
  if (!std::regex_search(header, m, std::regex("'descr'\\s*:\\s*'([^']+)'"))) throw_error(path, ": .npy header has no descr");
  a.descr = m[1];
  if (!std::regex_search(header, m, std::regex("'fortran_order'\\s*:\\s*(True|False)")))
    throw_error(path, ": .npy header has no fortran_order");
  a.fortran_order = m[1] == "True";
  if (!std::regex_search(header, m, std::regex("'shape'\\s*:\\s*\\(([^)]*)\\)"))) throw_error(path, ": .npy header has no shape");
  std::string dims = m[1];
  std::istringstream ds(dims);
  std::string tok;
  while (std::getline(ds, tok, ',')) {
    if (tok.find_first_not_of(" ") == std::string::npos) continue;
    a.shape.push_back(size_t(std::stoull(tok)));
  }
  size_t item = 0;
  const char kind = a.descr.size() >= 3 ? a.descr[1] : '?';
  if (a.descr.size() >= 3) item = size_t(std::atoi(a.descr.c_str() + 2));
  if (item == 0 || (kind != 'f' && kind != 'i' && kind != 'u')) throw_error(path, ": unsupported .npy dtype '", a.descr, "'");
  const size_t need = a.size() * item;
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
  if (fortran_order && shape.size() == 2) {
    std::vector<double> c(n);
    const size_t R = shape[0], C = shape[1];
    for (size_t r = 0; r < R; ++r)
      for (size_t k = 0; k < C; ++k) c[r * C + k] = out[k * R + r];
    return c;
  }
  if (fortran_order && shape.size() > 2) throw_error(source, ": Fortran-order arrays of rank > 2 are not supported");
  return out;
}

std::string npy_header(const std::string& descr, const std::vector<size_t>& shape) {
  std::ostringstream h;
  h << "{'descr': '" << descr << "', 'fortran_order': False, 'shape': (";
  for (size_t i = 0; i < shape.size(); ++i) h << shape[i] << (shape.size() == 1 ? "," : (i + 1 < shape.size() ? ", " : ""));
  h << "), }";
  std::string header = h.str();
  const size_t total = 10 + header.size() + 1;
  header.append((64 - total % 64) % 64, ' ');
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

NpyStreamWriter::NpyStreamWriter(const std::string& path, const std::string& descr, size_t item_bytes, const std::vector<size_t>& shape)
    : path_(path), tmp_(path + ".tmp" + std::to_string(::getpid())) {
  expected_ = item_bytes;
  for (size_t d : shape) expected_ *= d;
  const size_t slash = path.find_last_of('/');
  if (slash != std::string::npos && slash > 0) make_directories(path.substr(0, slash));
  FILE* f = std::fopen(tmp_.c_str(), "wb");
  if (!f) throw_error(path, ": cannot open for writing (", std::strerror(errno), ")");
  file_ = f;
  const std::string header = npy_header(descr, shape);
  if (std::fwrite(header.data(), 1, header.size(), f) != header.size()) throw_error(path, ": write failed");
}

NpyStreamWriter::~NpyStreamWriter() {
  if (file_) {
    std::fclose(static_cast<FILE*>(file_));
    std::remove(tmp_.c_str());
  }
}

void NpyStreamWriter::write(const void* data, size_t bytes) {
  FILLGS_CHECK(file_ != nullptr);
  if (written_ + bytes > expected_) throw_error(path_, ": more data than the shape holds");
  if (bytes && std::fwrite(data, 1, bytes, static_cast<FILE*>(file_)) != bytes) throw_error(path_, ": write failed (", std::strerror(errno), ")");
  written_ += bytes;
}

void NpyStreamWriter::finish() {
  FILLGS_CHECK(file_ != nullptr);
  if (written_ != expected_) throw_error(path_, ": ", written_, " bytes written, the shape needs ", expected_);
  FILE* f = static_cast<FILE*>(file_);
  file_ = nullptr;
  const bool ok = std::fflush(f) == 0;
  std::fclose(f);
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
