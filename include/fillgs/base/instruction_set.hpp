#pragma once
// The widest instruction set fillgs's kernels may use.
//
// fillgs's vector kernels (Google Highway: the tile kernel, the networks' dense layers, the
// loss's blur) and Embree's traversal choose the widest instruction set the CPU has, at run
// time. AVX2 and AVX-512 round differently, so the same command trains a slightly different
// model on each. The environment variable FILLGS_INSTRUCTION_SET caps both — `avx2`,
// `sse4` or `avx512`; unset, empty or `native`: the CPU's widest — so that a run recorded on
// an AVX2 machine can be continued, bit for bit, on an AVX-512 one (bench/README.md,
// "Resuming and identity").
#include <string>

namespace fillgs {

/// Caps the kernels at NAME (`avx2`, `sse4`, `avx512`; "" or `native`: no cap). Call before
/// any kernel runs. An unknown name, or one this CPU cannot run, is an Error
/// "WHERE: NAME ..." naming what is accepted or what the CPU has.
void limit_instruction_set(const std::string& name, const std::string& where);

/// limit_instruction_set() with the FILLGS_INSTRUCTION_SET environment variable, when set.
void limit_instruction_set_from_environment();

/// The cap in force: `avx2`, `sse4`, `avx512`, or "" when none.
const std::string& instruction_set_limit();

/// The instruction set the vector kernels run on now, as Highway names it (`AVX3`, `AVX2`, ...).
std::string kernel_instruction_set();

/// The configuration string Embree's device takes for the cap ("max_isa=avx2"), "" when none.
std::string embree_device_config();

}  // namespace fillgs
