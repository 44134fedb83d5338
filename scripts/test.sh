#!/usr/bin/env bash
# Installs, builds, and runs every test (Catch2 through CTest, plus the benchmark smoke runs).
# Tests read ../shared/data (or $FILLGS_SHARED_DATA).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
ctest --test-dir build --output-on-failure -j"$(nproc)"
