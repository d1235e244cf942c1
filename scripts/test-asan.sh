#!/usr/bin/env bash
# Builds the `fault` tests and the programs they run with AddressSanitizer and UBSan
# (-DLOOKUP_ASAN=ON, a build folder of its own) and runs `ctest -L fault` there. Any sanitizer
# finding aborts the program, so its test fails. scripts/test.sh calls this after the normal
# suite unless LOOKUP_SKIP_ASAN=1.
# Usage: bash scripts/test-asan.sh [ctest arguments...]
set -euo pipefail
cd "$(dirname "$0")/.."

BUILD_DIR=${LOOKUP_ASAN_BUILD_DIR:-build-asan}
JOBS=${LOOKUP_JOBS:-$(nproc)}
# Without LibTorch and benchmarks: no fault test needs them.
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLOOKUP_ASAN=ON \
    -DLOOKUP_WITH_TORCH=OFF -DLOOKUP_BUILD_BENCHMARKS=OFF
cmake --build "$BUILD_DIR" -j "$JOBS" --target lookup_fault_tests

# abort_on_error: a finding ends in SIGABRT, which the fault tests count as a crash, rather
# than exit 1, which some cases would accept as a refusal. Leak checking is off: it needs
# ptrace (refused in many CI containers) and reports MRPT's process-lifetime singletons.
export ASAN_OPTIONS=${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=0:check_initialization_order=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:abort_on_error=1:print_stacktrace=1}
cd "$BUILD_DIR"
ctest --output-on-failure -j "$JOBS" -L fault "$@"
