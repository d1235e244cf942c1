#!/usr/bin/env bash
# Installs dependencies, builds LookUP (Release) and runs the whole test suite with ctest.
# Then the `fault` tests again under AddressSanitizer/UBSan (scripts/test-asan.sh, its own
# build folder); LOOKUP_SKIP_ASAN=1 skips that part.
# Usage: bash scripts/test.sh [ctest arguments...]
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/install-deps.sh
BUILD_DIR=${LOOKUP_BUILD_DIR:-build}
JOBS=${LOOKUP_JOBS:-$(nproc)}
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$BUILD_DIR" -j "$JOBS"
(cd "$BUILD_DIR" && ctest --output-on-failure -j "$JOBS" "$@")
if [ "${LOOKUP_SKIP_ASAN:-0}" != 1 ]; then
    bash scripts/test-asan.sh
fi
