#!/usr/bin/env bash
# Installs, builds, and runs every test (Catch2 and pytest through CTest, plus the benchmark smoke runs),
# then the sanitizer tree: the reader, CLI, extremes and robustness tests under ASan + UBSan
# and a short smoke of every fuzz harness (tests/README.md, "Robustness").
# Tests read ../shared/data (or $FILLGS_SHARED_DATA).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh --tests
ctest --test-dir build --output-on-failure -j"$(nproc)"
bash scripts/build-fuzz.sh
ctest --test-dir build-fuzz --output-on-failure -j"$(nproc)"
