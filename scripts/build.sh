#!/usr/bin/env bash
# Installs missing dependencies (Debian 12 packages) and builds fillgs into build/.
#   scripts/build.sh           the fillgs program only (what the main job needs)
#   scripts/build.sh --tests   everything: tests, benchmarks, the Python module
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = --tests ]; then
  bash scripts/install-deps.sh --tests
  cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=ON -DFILLGS_REQUIRE_TESTS=ON
  cmake --build build -j"$(nproc)"
else
  bash scripts/install-deps.sh
  cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
  cmake --build build -j"$(nproc)" --target fillgs
fi
