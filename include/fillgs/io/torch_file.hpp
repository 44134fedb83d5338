#pragma once
// Readers for the archives the field's training code saves: zip archives (PyTorch's
// torch.save format, NumPy's .npz) and the pickle inside a torch.save archive.
//
// A torch.save file is a zip archive holding `<name>/data.pkl` (a pickle, protocol 2) and
// one raw little-endian storage per tensor, `<name>/data/<key>`. The pickle is run by a
// small virtual machine that knows the opcodes torch.save and pickle emit for state dicts,
// tuples, lists, numbers and strings; tensors are rebuilt from their storages (any dtype,
// any strides). It calls no Python code: a global other than the tensor rebuilders, the
// storage types and OrderedDict is kept as an opaque name, so a file can only describe
// data. Every problem is one fillgs::Error naming the file and what was wrong.
//
// Why our own reader and not libtorch (Debian's libtorch-dev): the two files we read are
// a state dict and a tuple; libtorch (libtorch1.13: 131 MB installed, by apt-cache, plus its
// dependencies) would add a C++ API to the build for that, and its own unpickler still
// needs the same walk over the values afterwards (data/README.md, "Reading .pth files").
#include <cstdint>
#include <string>
#include <map>
#include <memory>
#include <vector>

#include "fillgs/base/limits.hpp"

namespace fillgs {

/// A zip archive read whole: entries stored or deflated (zlib), zip64 included.
class ZipArchive {
 public:
  /// Reads `path`; throws "PATH: not a zip archive (...)" and the like.
  explicit ZipArchive(const std::string& path);
  ZipArchive(std::string bytes, std::string source);

  const std::string& source() const { return source_; }
  const std::vector<std::string>& names() const { return names_; }
  bool has(const std::string& name) const;
  /// The entry's bytes (CRC checked); throws naming the archive and the entry. Every read
  /// is charged to budget(), so re-reading an entry costs what reading it twice does.
  std::string read(const std::string& name) const;
  /// What this archive's reader has taken so far (entries read, and what its caller charges).
  AllocationBudget& budget() const { return budget_; }

 private:
  struct Entry {
    uint64_t local_offset = 0, compressed = 0, size = 0;
    uint32_t crc = 0;
    uint16_t method = 0;
  };
  void parse();
  std::string bytes_, source_;
  std::vector<std::string> names_;
  std::vector<Entry> entries_;
  mutable AllocationBudget budget_{source_};
};

/// A tensor's values converted to float (bool and integer dtypes too), C order.
struct TorchTensor {
  std::string dtype;            ///< "float32", "float64", "float16", "bfloat16", "int64", "int32", "int16", "int8", "uint8", "bool"
  std::vector<int64_t> shape;
  std::vector<float> values;
  size_t numel() const { return values.size(); }
  std::string shape_text() const;  ///< "[300, 256]"
};

/// The value tree of a pickle. Values live in an arena and are named by index, so a
/// pickle that builds a cycle costs nothing and nothing is freed recursively.
class PickleValues {
 public:
  enum class Kind { None, Bool, Int, Float, Str, Bytes, Tuple, List, Dict, Global, Tensor, Storage, Object, Mark };
  using Ref = uint32_t;

  Kind kind(Ref r) const { return values_[r].kind; }
  const char* kind_name(Ref r) const { return kind_text(kind(r)); }
  static const char* kind_text(Kind k);
  Ref root() const { return root_; }
  size_t value_count() const { return values_.size(); }

  bool is_number(Ref r) const { return kind(r) == Kind::Int || kind(r) == Kind::Float || kind(r) == Kind::Bool; }
  double number(Ref r) const;
  int64_t integer(Ref r) const;
  const std::string& text(Ref r) const { return values_[r].text; }
  /// Tuple or list items; dict entries are (key, value) pairs.
  const std::vector<Ref>& items(Ref r) const { return values_[r].items; }
  /// The value of string key `key` in dict `r`, or UINT32_MAX.
  Ref find(Ref dict, const std::string& key) const;

 protected:
  struct Value {
    Kind kind = Kind::None;
    int64_t i = 0;
    double f = 0;
    std::string text;          ///< Str, Bytes, Global "module.name", Storage key
    std::vector<Ref> items;    ///< Tuple/List items, Dict keys and values interleaved, Object (callable, args)
    // Tensor: storage ref in items[0]; Storage: dtype in text2
    std::string text2;
    int64_t offset = 0;
    std::vector<int64_t> shape, stride;
  };
  std::vector<Value> values_;
  Ref root_ = 0;
  friend class PickleMachine;
  friend void run_pickle(const std::string&, const std::string&, PickleValues&, AllocationBudget*);
};

/// A torch.save archive: its pickle's values and its tensors.
class TorchFile : public PickleValues {
 public:
  /// Reads `path` (a zip archive holding NAME/data.pkl). Legacy (pre-1.6, non-zip) files
  /// are refused with one line saying how to re-save them.
  explicit TorchFile(const std::string& path);

  const std::string& source() const { return source_; }
  /// What reading this file has taken so far (its entries, values and tensors); a reader
  /// charges what it will take because of the file (a network's working memory) to it too.
  AllocationBudget& budget() const { return zip_.budget(); }
  /// The tensor value `r` as floats; `what` names it in errors ("key 'weight'").
  TorchTensor tensor(Ref r, const std::string& what) const;
  /// The string-keyed entries of a dict (an OrderedDict state dict), in file order.
  std::vector<std::pair<std::string, Ref>> string_entries(Ref dict, const std::string& what) const;

 private:
  /// The bytes of storage `key`, inflated on first use; kept when more than one tensor
  /// views it, so that each storage is inflated once.
  std::shared_ptr<const std::string> storage(const std::string& key, const std::string& what) const;
  std::string source_;
  ZipArchive zip_;
  std::string prefix_;  ///< "archive/" or the saved file's stem
  /// Storages viewed by more than one tensor, by key, once read.
  mutable std::map<std::string, std::shared_ptr<const std::string>> storages_;
  std::map<std::string, int> views_;  ///< how many of the pickle's tensors view each storage
};

/// Runs a pickle held in `bytes` into `values` (exposed for the fuzz harness and tests);
/// the values' memory is charged to `budget` (a budget of its own when null).
void run_pickle(const std::string& bytes, const std::string& source, PickleValues& values, AllocationBudget* budget = nullptr);

}  // namespace fillgs
