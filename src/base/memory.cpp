#include "fillgs/base/memory.hpp"

#include <malloc.h>

namespace fillgs {

void keep_freed_memory() {
#if defined(__GLIBC__)
  // Blocks up to 32 MB (glibc's largest mmap threshold) come from the heap, and the heap is
  // not trimmed: a render's or a training iteration's buffers are reused next time instead
  // of being unmapped and faulted in again page by page (guitar at 1352×1014, 2 threads:
  // 72 → 52 ms per frame, `fillgs_bench render`).
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

}  // namespace fillgs
