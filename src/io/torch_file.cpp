#include "fillgs/io/torch_file.hpp"

#include <zlib.h>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <unordered_map>
#include <unordered_set>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"
#include "fillgs/base/limits.hpp"

namespace fillgs {

namespace {

uint64_t le(const std::string& b, size_t at, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v |= uint64_t(static_cast<unsigned char>(b[at + size_t(i)])) << (8 * i);
  return v;
}

}  // namespace

// ---------------------------------------------------------------------------------
// Zip

ZipArchive::ZipArchive(const std::string& path) : bytes_(read_file(path)), source_(path) { parse(); }

ZipArchive::ZipArchive(std::string bytes, std::string source) : bytes_(std::move(bytes)), source_(std::move(source)) { parse(); }

void ZipArchive::parse() {
  const std::string& b = bytes_;
  const size_t n = b.size();
  if (n < 22) throw_error(source_, ": not a zip archive (", n, " bytes, too short for its end record)");
  // The end-of-central-directory record sits within the last 22 + 65535 bytes.
  size_t eocd = std::string::npos;
  const size_t lowest = n > 22 + 65535 ? n - 22 - 65535 : 0;
  for (size_t at = n - 22 + 1; at-- > lowest;)
    if (le(b, at, 4) == 0x06054b50) {
      eocd = at;
      break;
    }
  if (eocd == std::string::npos) throw_error(source_, ": not a zip archive (no end-of-central-directory record: truncated?)");
  uint64_t count = le(b, eocd + 10, 2), cd_size = le(b, eocd + 12, 4), cd_offset = le(b, eocd + 16, 4);
  if (count == 0xFFFF || cd_size == 0xFFFFFFFF || cd_offset == 0xFFFFFFFF) {
    if (eocd < 20 || le(b, eocd - 20, 4) != 0x07064b50) throw_error(source_, ": zip64 archive without its zip64 locator");
    const uint64_t z = le(b, eocd - 20 + 8, 8);
    if (z > n - 56 || n < 56 || le(b, size_t(z), 4) != 0x06064b50) throw_error(source_, ": zip64 end record out of place");
    count = le(b, size_t(z) + 32, 8);
    cd_size = le(b, size_t(z) + 40, 8);
    cd_offset = le(b, size_t(z) + 48, 8);
  }
  if (cd_offset > n || cd_size > n - cd_offset) throw_error(source_, ": central directory lies outside the file (truncated?)");
  if (count > cd_size / 46) throw_error(source_, ": central directory holds ", count, " entries in ", cd_size, " bytes");
  std::unordered_set<std::string> seen;
  size_t at = size_t(cd_offset);
  const size_t end = size_t(cd_offset + cd_size);
  for (uint64_t e = 0; e < count; ++e) {
    if (end - at < 46 || le(b, at, 4) != 0x02014b50) throw_error(source_, ": central directory entry ", e, " is malformed");
    Entry en;
    const uint64_t flags = le(b, at + 8, 2);
    en.method = uint16_t(le(b, at + 10, 2));
    en.crc = uint32_t(le(b, at + 16, 4));
    en.compressed = le(b, at + 20, 4);
    en.size = le(b, at + 24, 4);
    const size_t name_len = le(b, at + 28, 2), extra_len = le(b, at + 30, 2), comment_len = le(b, at + 32, 2);
    en.local_offset = le(b, at + 42, 4);
    if (end - at - 46 < name_len + extra_len + comment_len) throw_error(source_, ": central directory entry ", e, " runs past its directory");
    std::string name = b.substr(at + 46, name_len);
    // Zip64 extra field: the 64-bit values of the fields that hold 0xFFFFFFFF, in order.
    size_t x = at + 46 + name_len;
    const size_t xend = x + extra_len;
    while (xend - x >= 4) {
      const uint64_t id = le(b, x, 2), len = le(b, x + 2, 2);
      if (len > xend - x - 4) break;
      if (id == 1) {
        size_t f = x + 4;
        auto take = [&](uint64_t& v) {
          if (v != 0xFFFFFFFF) return;
          if (f + 8 > x + 4 + len) throw_error(source_, ": entry '", name, "' has a short zip64 field");
          v = le(b, f, 8);
          f += 8;
        };
        take(en.size);
        take(en.compressed);
        take(en.local_offset);
      }
      x += 4 + size_t(len);
    }
    if (flags & 1) throw_error(source_, ": entry '", name, "' is encrypted");
    // Two entries of one name are read differently by different programs (NumPy takes the
    // last, a first-match reader the first): refused rather than choose.
    if (!seen.insert(name).second) throw_error(source_, ": entry '", name, "' appears twice in the central directory");
    if (en.method != 0 && en.method != 8)
      throw_error(source_, ": entry '", name, "' uses compression method ", en.method, " (fillgs reads stored and deflated entries)");
    names_.push_back(std::move(name));
    entries_.push_back(en);
    at += 46 + name_len + extra_len + comment_len;
  }
}

bool ZipArchive::has(const std::string& name) const { return std::find(names_.begin(), names_.end(), name) != names_.end(); }

std::string ZipArchive::read(const std::string& name) const {
  const auto it = std::find(names_.begin(), names_.end(), name);
  if (it == names_.end()) throw_error(source_, ": archive has no entry '", name, "'");
  const Entry& en = entries_[size_t(it - names_.begin())];
  const std::string& b = bytes_;
  if (en.local_offset > b.size() || b.size() - en.local_offset < 30 || le(b, size_t(en.local_offset), 4) != 0x04034b50)
    throw_error(source_, ": entry '", name, "': local header missing (truncated?)");
  const size_t data = size_t(en.local_offset) + 30 + le(b, size_t(en.local_offset) + 26, 2) + le(b, size_t(en.local_offset) + 28, 2);
  if (data > b.size() || en.compressed > b.size() - data)
    throw_error(source_, ": entry '", name, "' needs ", en.compressed, " bytes, the file ends ", b.size() - std::min(data, b.size()),
                " bytes after its start (truncated?)");
  budget_.charge(size_t(en.size), "entry '" + name + "' (" + std::to_string(en.size) + " bytes)");
  std::string out;
  if (en.method == 0) {
    if (en.size != en.compressed) throw_error(source_, ": stored entry '", name, "' has two sizes (", en.size, ", ", en.compressed, ")");
    out = b.substr(data, size_t(en.size));
  } else {
    // Deflate cannot expand more than ~1032:1; a larger claim is a corrupt header.
    if (en.size > en.compressed * 1032 + 1024) throw_error(source_, ": entry '", name, "' claims ", en.size, " bytes from ", en.compressed);
    out.resize(size_t(en.size));
    z_stream z{};
    if (inflateInit2(&z, -15) != Z_OK) throw_error(source_, ": cannot start zlib");
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(b.data() + data));
    z.avail_in = uInt(std::min<uint64_t>(en.compressed, std::numeric_limits<uInt>::max()));
    z.next_out = reinterpret_cast<Bytef*>(out.data());
    z.avail_out = uInt(std::min<uint64_t>(en.size, std::numeric_limits<uInt>::max()));
    const int rc = inflate(&z, Z_FINISH);
    const uint64_t produced = z.total_out;
    inflateEnd(&z);
    if (rc != Z_STREAM_END || produced != en.size)
      throw_error(source_, ": entry '", name, "' does not inflate to its ", en.size, " bytes (corrupt or truncated)");
  }
  uLong c = crc32(0L, Z_NULL, 0);
  for (size_t at = 0; at < out.size();) {
    const size_t step = std::min<size_t>(out.size() - at, 1u << 30);
    c = crc32(c, reinterpret_cast<const Bytef*>(out.data() + at), uInt(step));
    at += step;
  }
  if (uint32_t(c) != en.crc) throw_error(source_, ": entry '", name, "' fails its CRC check (corrupt)");
  return out;
}

// ---------------------------------------------------------------------------------
// Pickle

const char* PickleValues::kind_text(Kind k) {
  static const char* const names[] = {"None", "bool", "int", "float", "str", "bytes", "tuple", "list", "dict", "global", "tensor", "storage", "object", "mark"};
  return names[int(k)];
}

double PickleValues::number(Ref r) const { return kind(r) == Kind::Float ? values_[r].f : double(values_[r].i); }
int64_t PickleValues::integer(Ref r) const {
  if (kind(r) != Kind::Float) return values_[r].i;
  const double f = values_[r].f;
  // NaN, infinities and floats beyond int64 have no integer value (converting them is undefined).
  return f > -9.2e18 && f < 9.2e18 ? int64_t(f) : std::numeric_limits<int64_t>::min();
}

PickleValues::Ref PickleValues::find(Ref dict, const std::string& key) const {
  if (kind(dict) != Kind::Dict) return UINT32_MAX;
  const auto& it = values_[dict].items;
  for (size_t i = 0; i + 1 < it.size(); i += 2)
    if (kind(it[i]) == Kind::Str && values_[it[i]].text == key) return it[i + 1];
  return UINT32_MAX;
}

class PickleMachine {
 public:
  PickleMachine(const std::string& bytes, const std::string& source, PickleValues& out, AllocationBudget& budget)
      : b_(bytes), src_(source), v_(out.values_), budget_(budget) {}

  PickleValues::Ref run() {
    using K = PickleValues::Kind;
    while (true) {
      if (at_ >= b_.size()) fail("ends without a STOP opcode (truncated?)");
      const unsigned char op = static_cast<unsigned char>(b_[at_++]);
      switch (op) {
        case 0x80: take(1); break;                 // PROTO
        case 0x95: take(8); break;                 // FRAME
        case '}': push(make(K::Dict)); break;      // EMPTY_DICT
        case ']': push(make(K::List)); break;      // EMPTY_LIST
        case ')': push(make(K::Tuple)); break;     // EMPTY_TUPLE
        case 0x8f: push(make(K::List)); break;     // EMPTY_SET
        case '(': push(make(K::Mark)); break;      // MARK
        case 'N': push(make(K::None)); break;
        case 0x88: push(boolean(true)); break;
        case 0x89: push(boolean(false)); break;
        case 'J': push(integer(int64_t(int32_t(uint32_t(le(take(4), 0, 4)))))); break;
        case 'K': push(integer(int64_t(le(take(1), 0, 1)))); break;
        case 'M': push(integer(int64_t(le(take(2), 0, 2)))); break;
        case 0x8a: long_int(size_t(le(take(1), 0, 1))); break;
        case 0x8b: long_int(size_t(le(take(4), 0, 4))); break;
        case 'G': {
          const std::string s = take(8);
          uint64_t bits = 0;
          for (int i = 0; i < 8; ++i) bits = (bits << 8) | static_cast<unsigned char>(s[size_t(i)]);
          double d;
          std::memcpy(&d, &bits, 8);
          const auto r = make(K::Float);
          v_[r].f = d;
          push(r);
          break;
        }
        case 'X': push(str(K::Str, take(size_t(le(take(4), 0, 4))))); break;
        case 0x8c: push(str(K::Str, take(size_t(le(take(1), 0, 1))))); break;
        case 0x8d: push(str(K::Str, take(size_t(le(take(8), 0, 8))))); break;
        case 'T': push(str(K::Str, take(size_t(le(take(4), 0, 4))))); break;
        case 'U': push(str(K::Str, take(size_t(le(take(1), 0, 1))))); break;
        case 'B': push(str(K::Bytes, take(size_t(le(take(4), 0, 4))))); break;
        case 'C': push(str(K::Bytes, take(size_t(le(take(1), 0, 1))))); break;
        case 0x8e: push(str(K::Bytes, take(size_t(le(take(8), 0, 8))))); break;
        case 'c': {  // GLOBAL module\nname\n
          const std::string module = line(), name = line();
          push(str(K::Global, module + "." + name));
          break;
        }
        case 0x93: {  // STACK_GLOBAL
          const auto name = pop(), module = pop();
          if (v_[name].kind != K::Str || v_[module].kind != K::Str) fail("STACK_GLOBAL needs two strings");
          push(str(K::Global, v_[module].text + "." + v_[name].text));
          break;
        }
        case 'q': memo(size_t(le(take(1), 0, 1))); break;
        case 'r': memo(size_t(le(take(4), 0, 4))); break;
        case 0x94: memo(memo_.size()); break;  // MEMOIZE
        case 'h': recall(size_t(le(take(1), 0, 1))); break;
        case 'j': recall(size_t(le(take(4), 0, 4))); break;
        case 't': push(tuple(pop_mark())); break;
        case 0x85: push(tuple(popn(1))); break;
        case 0x86: push(tuple(popn(2))); break;
        case 0x87: push(tuple(popn(3))); break;
        case 'a': {
          const auto x = pop();
          append(top(), {x});
          break;
        }
        case 'e':
        case 0x90: {  // APPENDS, ADDITEMS
          auto xs = pop_mark();
          append(top(), xs);
          break;
        }
        case 's': {
          const auto val = pop(), key = pop();
          set_items(top(), {key, val});
          break;
        }
        case 'u': {
          auto kv = pop_mark();
          if (kv.size() % 2) fail("SETITEMS with an odd number of values");
          set_items(top(), kv);
          break;
        }
        case 'Q': {  // BINPERSID
          const auto pid = pop();
          push(storage(pid));
          break;
        }
        case 'R': {  // REDUCE
          const auto args = pop(), fn = pop();
          push(reduce(fn, args));
          break;
        }
        case 0x81: {  // NEWOBJ
          const auto args = pop(), cls = pop();
          push(reduce(cls, args));
          break;
        }
        case 'b': pop(); break;  // BUILD: state (an OrderedDict's _metadata, an object's __dict__) is not needed
        case '0': pop(); break;
        case '1': push(top()); break;
        case '2': pop_mark(); break;
        case '.': {
          if (stack_.size() != 1) fail("STOP with ", stack_.size(), " values on the stack");
          charge(0, true);
          return stack_.back();
        }
        default: fail("unsupported pickle opcode 0x", hex_byte(op), " at byte ", at_ - 1);
      }
    }
  }

 private:
  using Ref = PickleValues::Ref;
  using K = PickleValues::Kind;

  template <typename... Parts>
  [[noreturn]] void fail(const Parts&... parts) const {
    throw_error(src_, ": pickle ", parts...);
  }
  std::string take(size_t n) {
    if (n > b_.size() - at_) fail("runs past its end (", n, " bytes wanted at byte ", at_, ", truncated?)");
    std::string s = b_.substr(at_, n);
    at_ += n;
    return s;
  }
  std::string line() {
    const size_t e = b_.find('\n', at_);
    if (e == std::string::npos || e - at_ > 256) fail("GLOBAL name without a line end");
    std::string s = b_.substr(at_, e - at_);
    at_ = e + 1;
    return s;
  }
  /// Memory the values take, charged to the budget in steps of 1 MB (and at the end).
  void charge(size_t bytes, bool now = false) {
    pending_ += bytes;
    if (pending_ >= (size_t(1) << 20) || now) {
      budget_.charge(pending_, "pickle values (" + std::to_string(v_.size()) + " so far)");
      pending_ = 0;
    }
  }
  Ref make(K k) {
    if (v_.size() >= (size_t(1) << 31)) fail("holds too many values");
    // The arena doubles as it grows: charge what the vector holds, not only this value.
    charge(sizeof(PickleValues::Value) * (v_.size() == v_.capacity() ? std::max<size_t>(v_.size(), 1) : 0));
    v_.emplace_back();
    v_.back().kind = k;
    return Ref(v_.size() - 1);
  }
  Ref boolean(bool x) {
    const Ref r = make(K::Bool);
    v_[r].i = x;
    return r;
  }
  Ref integer(int64_t x) {
    const Ref r = make(K::Int);
    v_[r].i = x;
    return r;
  }
  Ref str(K k, std::string s) {
    charge(s.size());
    const Ref r = make(k);
    v_[r].text = std::move(s);
    return r;
  }
  void long_int(size_t n) {
    if (n > 8) fail("integer of ", n, " bytes is out of range");
    const std::string s = take(n);
    uint64_t u = 0;
    for (size_t i = 0; i < n; ++i) u |= uint64_t(static_cast<unsigned char>(s[i])) << (8 * i);
    if (n > 0 && n < 8 && (static_cast<unsigned char>(s[n - 1]) & 0x80)) u |= ~uint64_t(0) << (8 * n);  // sign-extend
    push(integer(int64_t(u)));
  }
  void push(Ref r) {
    if (stack_.size() > 100000) fail("stack deeper than 100000");
    stack_.push_back(r);
  }
  Ref top() {
    if (stack_.empty()) fail("opcode at byte ", at_ - 1, " needs a value, the stack is empty");
    return stack_.back();
  }
  Ref pop() {
    const Ref r = top();
    if (v_[r].kind == K::Mark) fail("opcode at byte ", at_ - 1, " meets a MARK");
    stack_.pop_back();
    return r;
  }
  std::vector<Ref> popn(size_t n) {
    std::vector<Ref> out(n);
    for (size_t i = n; i-- > 0;) out[i] = pop();
    return out;
  }
  std::vector<Ref> pop_mark() {
    size_t m = stack_.size();
    while (m > 0 && v_[stack_[m - 1]].kind != K::Mark) --m;
    if (m == 0) fail("opcode at byte ", at_ - 1, " finds no MARK");
    std::vector<Ref> out(stack_.begin() + ptrdiff_t(m), stack_.end());
    stack_.resize(m - 1);
    return out;
  }
  Ref tuple(std::vector<Ref> items) {
    charge(items.size() * sizeof(Ref));
    const Ref r = make(K::Tuple);
    v_[r].items = std::move(items);
    return r;
  }
  void memo(size_t index) {
    if (index > 10000000) fail("memo index ", index, " out of range");
    const auto [slot, fresh] = memo_.emplace(index, top());
    if (fresh) charge(64);  // a hash-map node
    else slot->second = top();
  }
  void recall(size_t index) {
    const auto it = memo_.find(index);
    if (it == memo_.end()) fail("recalls memo ", index, ", never stored");
    push(it->second);
  }
  void append(Ref list, const std::vector<Ref>& xs) {
    if (v_[list].kind != K::List) fail("APPEND to a ", kind_name(list));
    auto& items = v_[list].items;
    charge(xs.size() * sizeof(Ref));
    items.insert(items.end(), xs.begin(), xs.end());
  }
  void set_items(Ref dict, const std::vector<Ref>& kv) {
    if (v_[dict].kind != K::Dict) fail("SETITEM on a ", kind_name(dict));
    auto& items = v_[dict].items;
    charge(kv.size() * sizeof(Ref));
    items.insert(items.end(), kv.begin(), kv.end());
  }
  const char* kind_name(Ref r) const { return PickleValues::kind_text(v_[r].kind); }
  // BINPERSID: ('storage', storage_type, key, location, numel)
  Ref storage(Ref pid) {
    const auto& t = v_[pid];
    if (t.kind != K::Tuple || t.items.size() < 5 || v_[t.items[0]].kind != K::Str || v_[t.items[0]].text != "storage")
      fail("persistent id is not a ('storage', type, key, location, size) tuple");
    const Ref type = t.items[1], key = t.items[2], numel = t.items[4];
    if (v_[type].kind != K::Global || v_[key].kind != K::Str || v_[numel].kind != K::Int || v_[numel].i < 0)
      fail("persistent id of a storage has the wrong types");
    static const std::pair<const char*, const char*> kTypes[] = {
        {"torch.FloatStorage", "float32"}, {"torch.DoubleStorage", "float64"}, {"torch.HalfStorage", "float16"},
        {"torch.BFloat16Storage", "bfloat16"}, {"torch.LongStorage", "int64"}, {"torch.IntStorage", "int32"},
        {"torch.ShortStorage", "int16"}, {"torch.CharStorage", "int8"}, {"torch.ByteStorage", "uint8"},
        {"torch.BoolStorage", "bool"}, {"torch.UntypedStorage", "uint8"}};
    std::string dtype;
    for (const auto& [name, d] : kTypes)
      if (v_[type].text == name) dtype = d;
    if (dtype.empty()) fail("storage type '", v_[type].text.substr(0, 60), "' is not supported");
    const Ref r = make(K::Storage);
    v_[r].text = v_[key].text;
    v_[r].text2 = dtype;
    v_[r].offset = v_[numel].i;
    return r;
  }
  std::vector<int64_t> int_tuple(Ref r, const char* what) {
    if (v_[r].kind != K::Tuple) fail(what, " is a ", kind_name(r), ", not a tuple");
    if (v_[r].items.size() > 16) fail(what, " has ", v_[r].items.size(), " dimensions");
    std::vector<int64_t> out;
    for (Ref x : v_[r].items) {
      if (v_[x].kind != K::Int || v_[x].i < 0) fail(what, " holds a ", kind_name(x), " that is not a count");
      out.push_back(v_[x].i);
    }
    return out;
  }
  Ref reduce(Ref fn, Ref args) {
    const std::string name = v_[fn].kind == K::Global ? v_[fn].text : "";
    if (v_[args].kind != K::Tuple) {
      const Ref r = make(K::Object);
      v_[r].items = {fn, args};
      return r;
    }
    // The first four arguments only: copying a million-item tuple at every REDUCE that
    // recalls it would make a small pickle run for hours.
    const size_t count = v_[args].items.size();
    Ref a[4] = {UINT32_MAX, UINT32_MAX, UINT32_MAX, UINT32_MAX};
    for (size_t i = 0; i < std::min<size_t>(count, 4); ++i) a[i] = v_[args].items[i];
    if (name == "torch._utils._rebuild_tensor_v2" || name == "torch._utils._rebuild_tensor") {
      if (count < 4 || v_[a[0]].kind != K::Storage || v_[a[1]].kind != K::Int) fail(name, " with unexpected arguments");
      const Ref r = make(K::Tensor);
      v_[r].items = {a[0]};
      v_[r].offset = v_[a[1]].i;
      v_[r].shape = int_tuple(a[2], "tensor size");
      v_[r].stride = int_tuple(a[3], "tensor stride");
      if (v_[r].shape.size() != v_[r].stride.size() || v_[r].offset < 0) fail("tensor size and stride disagree");
      return r;
    }
    if (name == "torch._utils._rebuild_parameter" || name == "torch._utils._rebuild_parameter_with_state") {
      if (count == 0 || v_[a[0]].kind != K::Tensor) fail(name, " without a tensor");
      return a[0];
    }
    if (name == "collections.OrderedDict" || name == "builtins.dict") return make(K::Dict);
    if (name == "builtins.set" || name == "builtins.frozenset") {
      const Ref r = make(K::List);
      if (count > 0 && v_[a[0]].kind == K::List) {
        charge(v_[a[0]].items.size() * sizeof(Ref));
        v_[r].items = v_[a[0]].items;
      }
      return r;
    }
    const Ref r = make(K::Object);
    v_[r].items = {fn, args};
    return r;
  }

  const std::string& b_;
  const std::string& src_;
  std::vector<PickleValues::Value>& v_;
  AllocationBudget& budget_;
  size_t at_ = 0, pending_ = 0;
  std::vector<Ref> stack_;
  std::unordered_map<size_t, Ref> memo_;
};

void run_pickle(const std::string& bytes, const std::string& source, PickleValues& values, AllocationBudget* budget) {
  AllocationBudget own(source);
  PickleMachine m(bytes, source, values, budget ? *budget : own);
  values.root_ = m.run();
}

// ---------------------------------------------------------------------------------
// torch.save archives

TorchFile::TorchFile(const std::string& path)
    : source_(path), zip_([&] {
        require_regular_file(path);
        std::string head(4, '\0');
        if (FILE* f = std::fopen(path.c_str(), "rb")) {
          head.resize(std::fread(head.data(), 1, 4, f));
          std::fclose(f);
        }
        if (head.size() >= 2 && static_cast<unsigned char>(head[0]) == 0x80)
          throw_error(path, ": a legacy (pre-zip) torch.save file; re-save it with torch.save(obj, path) from PyTorch 1.6 or later");
        if (head.compare(0, 2, "PK") != 0) throw_error(path, ": not a torch.save archive (no zip signature)");
        return ZipArchive(path);
      }()) {
  std::string pkl;
  for (const std::string& n : zip_.names()) {
    const size_t slash = n.find('/');
    if (slash != std::string::npos && n.compare(slash, std::string::npos, "/data.pkl") == 0) {
      pkl = n;
      prefix_ = n.substr(0, slash + 1);
      break;
    }
  }
  if (pkl.empty()) throw_error(path, ": a zip archive without NAME/data.pkl: not a torch.save file");
  if (zip_.has(prefix_ + "byteorder")) {
    const std::string order = zip_.read(prefix_ + "byteorder");
    if (order != "little") throw_error(path, ": tensors stored ", order.substr(0, 20), "-endian; fillgs reads little-endian");
  }
  run_pickle(zip_.read(pkl), path + " (" + pkl + ")", *this, &zip_.budget());
  for (const Value& v : values_)
    if (v.kind == Kind::Tensor) ++views_[values_[v.items[0]].text];
}

std::string TorchTensor::shape_text() const {
  std::string s = "[";
  for (size_t i = 0; i < shape.size(); ++i) s += (i ? ", " : "") + std::to_string(shape[i]);
  return s + "]";
}

TorchTensor TorchFile::tensor(Ref r, const std::string& what) const {
  if (kind(r) != Kind::Tensor) throw_error(source_, ": ", what, " is a ", kind_name(r), ", not a tensor");
  const Value& t = values_[r];
  const Value& st = values_[t.items[0]];
  TorchTensor out;
  out.dtype = st.text2;
  out.shape = t.shape;
  const size_t item = out.dtype == "float64" || out.dtype == "int64" ? 8
                      : out.dtype == "float32" || out.dtype == "int32" ? 4
                      : out.dtype == "float16" || out.dtype == "bfloat16" || out.dtype == "int16" ? 2
                                                                                                   : 1;
  // Every extent is computed with checked arithmetic: a stride of 2^61 must not wrap the
  // last element's index around to a small one.
  const std::string sz = what + " extent";
  size_t numel = 1, last = size_t(t.offset);
  for (size_t d = 0; d < t.shape.size(); ++d) {
    numel = checked_mul(numel, size_t(t.shape[d]), source_, what + " size");
    if (t.shape[d] > 0) last = checked_add(last, checked_mul(size_t(t.shape[d] - 1), size_t(t.stride[d]), source_, sz), source_, sz);
  }
  const std::shared_ptr<const std::string> held = storage(st.text, what);
  const std::string& data = *held;
  const size_t have = data.size() / item;
  const size_t declared = size_t(st.offset);
  if (declared != have || data.size() % item)
    throw_error(source_, ": ", what, ": its storage '", st.text.substr(0, 40), "' declares ", declared, " elements of ", out.dtype, ", its entry holds ",
                data.size(), " bytes");
  if (numel > 0 && last >= have)
    throw_error(source_, ": ", what, " of shape ", out.shape_text(), " reaches element ", last, " of a storage of ", have);
  // Zero strides repeat elements; a saved parameter repeats none, so a tensor far larger than
  // its storage is a corrupt header, not data.
  if (numel > 64 * std::max<size_t>(have, 1) + 1024)
    throw_error(source_, ": ", what, " of shape ", out.shape_text(), " has ", numel, " elements from a storage of ", have);
  zip_.budget().charge(checked_mul(numel, sizeof(float), source_, what + " size"), what + " (" + std::to_string(numel) + " values)");
  out.values.resize(numel);
  std::vector<int64_t> idx(t.shape.size(), 0);
  for (size_t i = 0; i < numel; ++i) {
    size_t e = size_t(t.offset);
    for (size_t d = 0; d < idx.size(); ++d) e += size_t(idx[d]) * size_t(t.stride[d]);
    const char* p = data.data() + e * item;
    float v = 0;
    if (out.dtype == "float32") {
      std::memcpy(&v, p, 4);
    } else if (out.dtype == "float64") {
      double d;
      std::memcpy(&d, p, 8);
      v = float(d);
    } else if (out.dtype == "float16") {
      v = float(Eigen::numext::bit_cast<Eigen::half>(uint16_t(le(data, e * 2, 2))));
    } else if (out.dtype == "bfloat16") {
      v = float(Eigen::numext::bit_cast<Eigen::bfloat16>(uint16_t(le(data, e * 2, 2))));
    } else if (out.dtype == "int64") {
      v = float(int64_t(le(data, e * 8, 8)));
    } else if (out.dtype == "int32") {
      v = float(int32_t(uint32_t(le(data, e * 4, 4))));
    } else if (out.dtype == "int16") {
      v = float(int16_t(uint16_t(le(data, e * 2, 2))));
    } else if (out.dtype == "int8") {
      v = float(int8_t(static_cast<unsigned char>(*p)));
    } else {
      v = float(static_cast<unsigned char>(*p));
      if (out.dtype == "bool") v = v != 0.0f ? 1.0f : 0.0f;
    }
    out.values[i] = v;
    for (size_t d = idx.size(); d-- > 0;) {
      if (++idx[d] < t.shape[d]) break;
      idx[d] = 0;
    }
  }
  return out;
}

std::shared_ptr<const std::string> TorchFile::storage(const std::string& key, const std::string& what) const {
  const auto it = storages_.find(key);
  if (it != storages_.end()) return it->second;
  const std::string entry = prefix_ + "data/" + key;
  if (!zip_.has(entry)) throw_error(source_, ": ", what, ": its storage '", key.substr(0, 40), "' has no entry ", entry.substr(0, 80), " in the archive");
  auto bytes = std::make_shared<const std::string>(zip_.read(entry));
  // Kept only when another tensor views it too: a state dict's usual one storage per tensor
  // is not held twice (as bytes and as floats) while the model is read.
  const auto viewers = views_.find(key);
  if (viewers != views_.end() && viewers->second > 1) storages_.emplace(key, bytes);
  return bytes;
}

std::vector<std::pair<std::string, PickleValues::Ref>> TorchFile::string_entries(Ref dict, const std::string& what) const {
  if (kind(dict) != Kind::Dict) throw_error(source_, ": ", what, " is a ", kind_name(dict), ", not a state dict");
  std::vector<std::pair<std::string, Ref>> out;
  const auto& it = values_[dict].items;
  for (size_t i = 0; i + 1 < it.size(); i += 2)
    if (kind(it[i]) == Kind::Str) out.emplace_back(values_[it[i]].text, it[i + 1]);
  return out;
}

}  // namespace fillgs
