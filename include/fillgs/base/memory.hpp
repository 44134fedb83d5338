#pragma once
// Process-wide allocation policy for the front ends (fillgs, fillgs_bench).

namespace fillgs {

/// Keeps freed blocks of up to 32 MB in the heap instead of returning them to the system
/// (glibc mallopt; no effect elsewhere). Per-frame buffers are then reused without page
/// faults; resident memory stays at its high-water mark. Call once, first thing in main().
void keep_freed_memory();

}  // namespace fillgs
