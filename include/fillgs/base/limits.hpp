#pragma once
// Sizes taken on a file's word are checked before memory is taken (tests/README.md, "Robustness").
//
// Readers never allocate from a count they read without first checking it against the
// bytes left in the file (a record cannot be smaller than its fixed fields) or against
// allocation_cap(); arithmetic on sizes goes through checked_mul. Library exceptions a
// reader's input can provoke (nlohmann-json's type errors, std::sto*, bad_alloc) are turned
// into one-line fillgs::Errors naming the file by reading().
#include <cstddef>
#include <exception>
#include <new>
#include <string>

#include "fillgs/base/error.hpp"

namespace fillgs {

/// The largest image side fillgs accepts, in pixels (cameras, image files, video frames).
constexpr int kMaxImageSide = 65536;

/// An image side stored as a number: a whole number in [1, kMaxImageSide], else one line
/// "SOURCE: ELEMENT WHAT v is not a whole number of pixels in [1, 65536]".
int image_side(double v, const std::string& source, const std::string& element, const char* what);

/// The memory this process may use: the smallest of physical memory, its address-space
/// and data limits (ulimit -v, -d) and its cgroup's limit (v2 memory.max, v1
/// memory.limit_in_bytes), with the name of the one that sets it.
struct MemoryLimit {
  size_t bytes = 0;
  const char* source = "";
};
MemoryLimit memory_limit();

/// The most bytes one allocation may take: memory_limit(), or the FILLGS_MAX_ALLOC
/// environment variable (bytes) when set (tests use it). The default image budget of a
/// dataset is a quarter of it.
size_t allocation_cap();

/// a · b, or an Error "SOURCE: WHAT overflows (a × b)".
size_t checked_mul(size_t a, size_t b, const std::string& source, const std::string& what);

/// a + b, or an Error "SOURCE: WHAT overflows (a + b)".
size_t checked_add(size_t a, size_t b, const std::string& source, const std::string& what);

/// The bytes one reader has taken so far, charged before each allocation: a file whose
/// parts are each small enough but together are not (a pickle of ten million values, one
/// storage viewed by hundreds of tensors) is refused at the part that crosses
/// allocation_cap(), naming it: "SOURCE: WHAT would bring this file's memory to N bytes,
/// more than ...".
class AllocationBudget {
 public:
  explicit AllocationBudget(std::string source) : source_(std::move(source)) {}
  void charge(size_t bytes, const std::string& what);

 private:
  std::string source_;
  size_t used_ = 0, cap_ = 0;
};

/// Throws "SOURCE: WHAT would need N bytes, more than the M this process may use (LIMIT)"
/// when bytes > allocation_cap().
void check_allocation(size_t bytes, const std::string& source, const std::string& what);

/// A non-negative integer from decimal text (digits only, optional surrounding blanks), at
/// most `max`; throws "SOURCE: WHAT 'text' is not an integer in [0, max]".
size_t parse_count(const std::string& text, size_t max, const std::string& source, const std::string& what);

/// A finite number from the whole of `text` (blanks around it allowed) into *out; false
/// (and *out untouched) when the text is anything else.
bool parse_number(const std::string& text, double* out);

/// As above, but throws
/// "SOURCE: WHAT 'text' is not a number" (the text is cut to 40 characters in the message).
double parse_number(const std::string& text, const std::string& source, const std::string& what);

/// A byte as two lower-case hex digits ("ff"), for messages about bytes.
std::string hex_byte(unsigned char byte);

/// The index of the first byte of `text` that does not belong to well-formed UTF-8
/// (overlong forms, surrogates and code points past U+10FFFF included), or npos.
size_t first_invalid_utf8(const std::string& text);

/// Runs a reader. fillgs::Errors and Cancelled pass through; any other exception the input can provoke
/// becomes "SOURCE: malformed (what)" or "SOURCE: a size in the file needs more memory than
/// this machine has", so no message names nothing.
template <typename F>
auto reading(const std::string& source, F&& read) -> decltype(read()) {
  try {
    return read();
  } catch (const Error&) {
    throw;
  } catch (const Cancelled&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw_error(source, ": a size in the file needs more memory than this machine has");
  } catch (const std::exception& e) {
    throw_error(source, ": malformed (", e.what(), ")");
  }
}

}  // namespace fillgs
