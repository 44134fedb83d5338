#!/usr/bin/env bash
# Installs, builds, and runs the main job (`fillgs run`) on the built-in default scene.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
build/bin/fillgs run --out fillgs_run "$@"
