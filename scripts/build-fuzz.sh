#!/usr/bin/env bash
# The second build tree (tests/README.md, "Robustness"): clang with AddressSanitizer +
# UndefinedBehaviorSanitizer, the libFuzzer harnesses of tests/fuzz, and the robustness
# tests, into build-fuzz/. Needs clang and libclang-rt-14-dev (scripts/install-deps.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
# Default targets: the sanitized tests and every harness (pass others, e.g. fillgs, to add them).
targets=${*:-fillgs_tests fillgs_model_tests fuzz_all}
CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS=-gline-tables-only -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" \
  -DFILLGS_SANITIZE=ON -DFILLGS_FUZZ=ON -DBUILD_TESTING=ON -DFILLGS_MPI=OFF -DFILLGS_PYTHON=OFF -DFILLGS_REQUIRE_TESTS=ON
cmake --build build-fuzz -j"$(nproc)" --target $targets
