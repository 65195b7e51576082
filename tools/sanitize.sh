#!/usr/bin/env bash
# The sanitizer part of the README's test command (docs/RELIABILITY.md): one clang build with
# AddressSanitizer + UndefinedBehaviorSanitizer (the "fuzz" CMake preset, build-fuzz/) runs the unit
# and end-to-end suites, then every libFuzzer target briefly on its corpus.
#   tools/sanitize.sh [FUZZ_SECONDS_PER_TARGET=30]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-30}"
started=$SECONDS
cmake --preset fuzz >/dev/null
cmake --build build-fuzz -j "$(nproc)"
echo "sanitize.sh: build (clang ASan+UBSan) $((SECONDS - started)) s"
# Cyclone's and DCMTK's process-lifetime allocations are not ours to chase: leaks are reported by
# the fuzzers (a leak per input grows), not by every test process at exit.
export ASAN_OPTIONS="detect_leaks=0:abort_on_error=1:strict_string_checks=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
started=$SECONDS
ctest --test-dir build-fuzz -j "$(nproc)" --output-on-failure --timeout 900
echo "sanitize.sh: tests under ASan+UBSan $((SECONDS - started)) s"
started=$SECONDS
ASAN_OPTIONS="abort_on_error=1" bash tools/fuzz.sh "$seconds"
echo "sanitize.sh: fuzzers $((SECONDS - started)) s"
