#include "fillgs/base/limits.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sys/resource.h>
#include <unistd.h>

#include <fstream>
#include <string>
#include <utility>

namespace fillgs {

namespace {

/// A cgroup's memory limit in bytes from its file ("max" or unreadable: none).
size_t cgroup_limit(const char* file) {
  std::ifstream in(file);
  std::string text;
  if (!(in >> text) || text == "max") return 0;
  char* end = nullptr;
  const unsigned long long v = std::strtoull(text.c_str(), &end, 10);
  // cgroup v1 writes "no limit" as a huge number near 2^63.
  return end != text.c_str() && *end == '\0' && v < (1ull << 60) ? size_t(v) : 0;
}

}  // namespace

MemoryLimit memory_limit() {
  MemoryLimit m;
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  m.bytes = pages > 0 && page > 0 ? size_t(pages) * size_t(page) : size_t(1) << 36;  // 64 GiB when the system does not say
  m.source = "physical memory";
  auto lower = [&](size_t bytes, const char* source) {
    if (bytes > 0 && bytes < m.bytes) m.bytes = bytes, m.source = source;
  };
  for (const auto& [resource, name] : {std::pair<int, const char*>{RLIMIT_AS, "ulimit -v"}, {RLIMIT_DATA, "ulimit -d"}}) {
    rlimit r{};
    if (::getrlimit(resource, &r) == 0 && r.rlim_cur != RLIM_INFINITY) lower(size_t(r.rlim_cur), name);
  }
  lower(cgroup_limit("/sys/fs/cgroup/memory.max"), "the cgroup's memory.max");
  lower(cgroup_limit("/sys/fs/cgroup/memory/memory.limit_in_bytes"), "the cgroup's memory.limit_in_bytes");
  return m;
}

size_t allocation_cap() {
  if (const char* env = std::getenv("FILLGS_MAX_ALLOC")) {
    char* end = nullptr;
    const unsigned long long v = std::strtoull(env, &end, 10);
    if (end != env && *end == '\0' && v > 0) return size_t(v);
  }
  return memory_limit().bytes;
}

int image_side(double v, const std::string& source, const std::string& element, const char* what) {
  if (!(v >= 1 && v <= kMaxImageSide) || v != std::floor(v))
    throw_error(source, ": ", element, " ", what, " ", v, " is not a whole number of pixels in [1, ", kMaxImageSide, "]");
  return int(v);
}

size_t checked_mul(size_t a, size_t b, const std::string& source, const std::string& what) {
  if (a != 0 && b > std::numeric_limits<size_t>::max() / a) throw_error(source, ": ", what, " overflows (", a, " x ", b, ")");
  return a * b;
}

size_t checked_add(size_t a, size_t b, const std::string& source, const std::string& what) {
  if (b > std::numeric_limits<size_t>::max() - a) throw_error(source, ": ", what, " overflows (", a, " + ", b, ")");
  return a + b;
}

void AllocationBudget::charge(size_t bytes, const std::string& what) {
  if (cap_ == 0) cap_ = allocation_cap();
  const size_t total = checked_add(used_, bytes, source_, what);
  if (total > cap_) {
    const char* limit = std::getenv("FILLGS_MAX_ALLOC") ? "FILLGS_MAX_ALLOC" : memory_limit().source;
    throw_error(source_, ": ", what, " would bring this file's memory to ", total, " bytes, more than the ", cap_, " this process may use (",
                limit, ")");
  }
  used_ = total;
}

void check_allocation(size_t bytes, const std::string& source, const std::string& what) {
  const size_t cap = allocation_cap();
  if (bytes <= cap) return;
  if (std::getenv("FILLGS_MAX_ALLOC")) throw_error(source, ": ", what, " would need ", bytes, " bytes, more than FILLGS_MAX_ALLOC's ", cap);
  const MemoryLimit m = memory_limit();
  throw_error(source, ": ", what, " would need ", bytes, " bytes, more than the ", cap, " this process may use (", m.source, ")");
}

std::string hex_byte(unsigned char byte) {
  const char* d = "0123456789abcdef";
  return std::string{d[byte >> 4], d[byte & 15]};
}

size_t first_invalid_utf8(const std::string& text) {
  const size_t n = text.size();
  for (size_t i = 0; i < n;) {
    const unsigned c = static_cast<unsigned char>(text[i]);
    if (c < 0x80) {
      ++i;
      continue;
    }
    size_t len = 0;
    unsigned lo = 0x80, hi = 0xBF;  // the allowed range of the second byte (RFC 3629, table 3-7)
    if (c >= 0xC2 && c <= 0xDF) len = 2;
    else if (c >= 0xE0 && c <= 0xEF) len = 3, lo = c == 0xE0 ? 0xA0 : 0x80, hi = c == 0xED ? 0x9F : 0xBF;
    else if (c >= 0xF0 && c <= 0xF4) len = 4, lo = c == 0xF0 ? 0x90 : 0x80, hi = c == 0xF4 ? 0x8F : 0xBF;
    else return i;
    if (n - i < len) return i;
    for (size_t k = 1; k < len; ++k) {
      const unsigned b = static_cast<unsigned char>(text[i + k]);
      if (k == 1 ? (b < lo || b > hi) : (b < 0x80 || b > 0xBF)) return i;
    }
    i += len;
  }
  return std::string::npos;
}

namespace {
std::string excerpt(const std::string& text) { return text.size() > 40 ? text.substr(0, 40) + "..." : text; }
size_t trim_front(const std::string& s) {
  size_t i = 0;
  while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
  return i;
}
size_t trim_back(const std::string& s, size_t from) {
  size_t e = s.size();
  while (e > from && (s[e - 1] == ' ' || s[e - 1] == '\t' || s[e - 1] == '\r' || s[e - 1] == '\n')) --e;
  return e;
}
}  // namespace

size_t parse_count(const std::string& text, size_t max, const std::string& source, const std::string& what) {
  const size_t b = trim_front(text), e = trim_back(text, b);
  bool ok = e > b;
  size_t v = 0;
  for (size_t i = b; ok && i < e; ++i) {
    const char c = text[i];
    if (c < '0' || c > '9') ok = false;
    else if (v > (max - size_t(c - '0')) / 10) ok = false;  // v·10 + digit > max
    else v = v * 10 + size_t(c - '0');
  }
  if (!ok) throw_error(source, ": ", what, " '", excerpt(text), "' is not an integer in [0, ", max, "]");
  return v;
}

bool parse_number(const std::string& text, double* out) {
  const size_t b = trim_front(text), e = trim_back(text, b);
  const std::string t = text.substr(b, e - b);
  char* end = nullptr;
  const double v = t.empty() ? 0.0 : std::strtod(t.c_str(), &end);
  if (t.empty() || end != t.c_str() + t.size() || !std::isfinite(v)) return false;
  *out = v;
  return true;
}

double parse_number(const std::string& text, const std::string& source, const std::string& what) {
  double v = 0;
  if (!parse_number(text, &v)) throw_error(source, ": ", what, " '", excerpt(text), "' is not a number");
  return v;
}

}  // namespace fillgs
