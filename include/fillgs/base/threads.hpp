#pragma once
// Threads. fillgs's parallel loops are TBB loops that run in the caller's task arena, so no
// option struct carries a thread count: a program limits them for a scope with
// ThreadLimit (what `fillgs --threads n` does), or runs a call inside
// `tbb::task_arena(n).execute(...)` to give that call n threads. The results do not depend
// on the count (the tests compare 1 thread with several, bit for bit).
#include <memory>

#include <tbb/global_control.h>

namespace fillgs {

/// While it lives, at most `threads` threads run fillgs's loops (TBB's
/// max_allowed_parallelism, process-wide); 0 leaves the limit as it is (all cores).
class ThreadLimit {
 public:
  explicit ThreadLimit(int threads) {
    if (threads > 0)
      control_ = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(threads));
  }

 private:
  std::unique_ptr<tbb::global_control> control_;
};

}  // namespace fillgs
