#pragma once
// Hand-made torch.save archives for the tests that must feed fillgs's .pth reader what
// PyTorch itself refuses to write: strides that wrap 2^64 around, storages that declare more
// elements than they hold, pickles of millions of values, one storage viewed by hundreds of
// tensors. The layout is torch.save's (a zip archive holding archive/data.pkl, a protocol 2
// pickle of a state dict, and one raw storage per key under archive/data/); the pickle is
// written opcode by opcode, as Python's pickle module would for the same values.
#include <zlib.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace fillgs::test {

/// A protocol 2 pickle written opcode by opcode.
struct Pickle {
  std::string b = std::string("\x80\x02", 2);  // PROTO 2
  Pickle& raw(const std::string& s) {
    b += s;
    return *this;
  }
  Pickle& op(char c) {
    b += c;
    return *this;
  }
  Pickle& str(const std::string& s) {  // BINUNICODE
    b += 'X';
    for (int i = 0; i < 4; ++i) b += char((s.size() >> (8 * i)) & 0xff);
    b += s;
    return *this;
  }
  Pickle& integer(int64_t v) {  // LONG1 with 8 bytes: any int64
    b += '\x8a';
    b += char(8);
    for (int i = 0; i < 8; ++i) b += char((uint64_t(v) >> (8 * i)) & 0xff);
    return *this;
  }
  Pickle& number(double v) {  // BINFLOAT, big-endian
    uint64_t bits;
    static_assert(sizeof bits == sizeof v);
    __builtin_memcpy(&bits, &v, 8);
    b += 'G';
    for (int i = 7; i >= 0; --i) b += char((bits >> (8 * i)) & 0xff);
    return *this;
  }
  Pickle& global(const std::string& module, const std::string& name) { return op('c').raw(module + "\n" + name + "\n"); }
  Pickle& ints(const std::vector<int64_t>& v) {  // a tuple of ints
    op('(');
    for (int64_t x : v) integer(x);
    return op('t');
  }
};

/// One tensor of a state dict: a view (offset, shape, stride) of storage `storage`, which
/// declares `declared` float32 elements.
struct CraftTensor {
  std::string key, storage;
  int64_t declared = 0, offset = 0;
  std::vector<int64_t> shape, stride;
};

/// The pickle of a state dict {key: tensor} as torch.save writes it.
inline std::string state_dict_pickle(const std::vector<CraftTensor>& tensors) {
  Pickle p;
  p.global("collections", "OrderedDict").op(')').op('R');  // OrderedDict()
  p.op('(');
  for (const CraftTensor& t : tensors) {
    p.str(t.key);
    p.global("torch._utils", "_rebuild_tensor_v2");
    p.op('(');
    p.op('(').str("storage").global("torch", "FloatStorage").str(t.storage).str("cpu").integer(t.declared).op('t').op('Q');
    p.integer(t.offset).ints(t.shape).ints(t.stride).op('\x89');
    p.global("collections", "OrderedDict").op(')').op('R');
    p.op('t').op('R');
  }
  p.op('u').op('.');
  return p.b;
}

/// A zip archive of `entries` (name, bytes), each stored, or deflated where `deflate`.
inline std::string zip_of(const std::vector<std::pair<std::string, std::string>>& entries, bool compress = false) {
  auto u16 = [](std::string& s, uint32_t v) { s += char(v & 0xff), s += char((v >> 8) & 0xff); };
  auto u32 = [&](std::string& s, uint32_t v) { u16(s, v & 0xffff), u16(s, v >> 16); };
  std::string out, cd;
  for (const auto& entry : entries) {
    const std::string &name = entry.first, &data = entry.second;  // named: clang 14's lambdas cannot capture bindings
    const uint32_t crc = uint32_t(crc32(0L, reinterpret_cast<const Bytef*>(data.data()), uInt(data.size())));
    std::string body = data;
    if (compress) {
      z_stream z{};
      deflateInit2(&z, 9, Z_DEFLATED, -15, 9, Z_DEFAULT_STRATEGY);
      body.resize(deflateBound(&z, uLong(data.size())));
      z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
      z.avail_in = uInt(data.size());
      z.next_out = reinterpret_cast<Bytef*>(body.data());
      z.avail_out = uInt(body.size());
      deflate(&z, Z_FINISH);
      body.resize(z.total_out);
      deflateEnd(&z);
    }
    const uint32_t at = uint32_t(out.size());
    auto header = [&](std::string& s, bool central) {
      u32(s, central ? 0x02014b50 : 0x04034b50);
      if (central) u16(s, 20);
      u16(s, 20), u16(s, 0), u16(s, compress ? 8 : 0), u16(s, 0), u16(s, 0);
      u32(s, crc), u32(s, uint32_t(body.size())), u32(s, uint32_t(data.size()));
      u16(s, uint32_t(name.size())), u16(s, 0);
      if (central) u16(s, 0), u16(s, 0), u16(s, 0), u32(s, 0), u32(s, at);
      s += name;
    };
    header(out, false);
    out += body;
    header(cd, true);
  }
  const uint32_t cd_at = uint32_t(out.size());
  out += cd;
  u32(out, 0x06054b50), u16(out, 0), u16(out, 0), u16(out, uint32_t(entries.size())), u16(out, uint32_t(entries.size()));
  u32(out, uint32_t(cd.size())), u32(out, cd_at), u16(out, 0);
  return out;
}

/// A torch.save archive of a state dict: its pickle and the storages (key, float32 bytes).
inline std::string craft_pth(const std::vector<CraftTensor>& tensors, const std::vector<std::pair<std::string, std::string>>& storages,
                             bool compress = false) {
  std::vector<std::pair<std::string, std::string>> entries{{"archive/data.pkl", state_dict_pickle(tensors)}};
  for (const auto& [key, bytes] : storages) entries.emplace_back("archive/data/" + key, bytes);
  entries.emplace_back("archive/version", "3\n");
  return zip_of(entries, compress);
}

/// `n` float32 values 0, 1, 2, ... as a storage's bytes.
inline std::string float_storage(size_t n) {
  std::string s(n * 4, '\0');
  for (size_t i = 0; i < n; ++i) {
    const float v = float(i);
    __builtin_memcpy(&s[i * 4], &v, 4);
  }
  return s;
}

}  // namespace fillgs::test
