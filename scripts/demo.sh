#!/usr/bin/env bash
# The built-in example from a fresh machine: install, build, generate the small synthetic mine
# `mine-b-mini` and print its summary.
# Usage: bash scripts/demo.sh [OUT_DIR]   (default: demo-out)
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-demo-out}

bash scripts/install-deps.sh
BUILD_DIR=${LOOKUP_BUILD_DIR:-build}
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$BUILD_DIR" -j "$(nproc)"
BIN="$BUILD_DIR/bin"

echo "== 1. synthetic mine (lookup-sim) =="
"$BIN/lookup-sim" --preset mine-b-mini --out "$OUT/mine-b-mini" --seed 1
