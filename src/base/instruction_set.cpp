#include "fillgs/base/instruction_set.hpp"

#include <hwy/targets.h>

#include <cstdlib>

#include "fillgs/base/error.hpp"

namespace fillgs {

namespace {

struct Cap {
  const char* name;   // FILLGS_INSTRUCTION_SET's word
  int64_t target;     // Highway's target bit (lower bits are wider targets)
  const char* embree; // Embree's max_isa word
};

constexpr Cap kCaps[] = {
    {"avx512", HWY_AVX3, "avx512"},
    {"avx2", HWY_AVX2, "avx2"},
    {"sse4", HWY_SSE4, "sse4.2"},
};

/// hwy::SupportedTargets(), leaving dispatch as it was: the call itself points Highway's
/// chosen target at every target the CPU has (it sets dispatch up before applying
/// DisableTargets' mask, and leaves the final update to HWY_DYNAMIC_DISPATCH's first call),
/// so dispatch is pointed back at the supported set.
int64_t supported_targets() {
  const int64_t targets = hwy::SupportedTargets();
  hwy::GetChosenTarget().Update(targets);
  return targets;
}

std::string& limit() {
  static std::string name;
  return name;
}

const Cap* find_cap(const std::string& name) {
  for (const Cap& c : kCaps)
    if (name == c.name) return &c;
  return nullptr;
}

}  // namespace

void limit_instruction_set(const std::string& name, const std::string& where) {
  if (name.empty() || name == "native") {
    hwy::DisableTargets(0);
    limit().clear();
    return;
  }
  const Cap* cap = find_cap(name);
  if (!cap) throw_error(where, ": '", name, "' is not an instruction set fillgs can be held to (avx512, avx2, sse4 or native)");
  hwy::DisableTargets(0);  // what the CPU has, before any earlier cap
  if ((supported_targets() & cap->target) == 0)
    throw_error(where, ": this CPU cannot run ", name, " (its widest for fillgs's kernels is ", kernel_instruction_set(), ")");
  // Every target wider than the cap (lower bits) is disabled; Highway dispatches to the
  // widest that is left, the cap itself.
  hwy::DisableTargets(cap->target - 1);
  limit() = name;
}

void limit_instruction_set_from_environment() {
  if (const char* env = std::getenv("FILLGS_INSTRUCTION_SET")) limit_instruction_set(env, "FILLGS_INSTRUCTION_SET");
}

const std::string& instruction_set_limit() { return limit(); }

std::string kernel_instruction_set() {
  // The widest target both compiled in and supported (the lowest bit): what dispatch picks.
  const int64_t targets = supported_targets() & HWY_TARGETS;
  return hwy::TargetName(targets & -targets);
}

std::string embree_device_config() {
  const Cap* cap = find_cap(limit());
  return cap ? std::string("max_isa=") + cap->embree : std::string();
}

}  // namespace fillgs
