#pragma once
// The one thread-count convention of every option struct's `threads`: n > 0 threads, or 0
// for all cores.
#include <tbb/task_arena.h>

namespace fillgs {

/// The concurrency of a tbb::task_arena for an option's `threads` (0: all cores).
inline int arena_concurrency(int threads) { return threads > 0 ? threads : tbb::task_arena::automatic; }

}  // namespace fillgs
