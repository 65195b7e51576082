#!/usr/bin/env bash
# The README's test command: install dependencies, check formatting, build, run every test suite;
# then the same suites under AddressSanitizer + UndefinedBehaviorSanitizer and each fuzzer for a
# while (tools/sanitize.sh). IGNAV_SANITIZE=0 skips that second part (a quicker local run).
# Each phase's time is printed as it ends, and all of them at the end (CI has 90 minutes).
set -euo pipefail
cd "$(dirname "$0")/.."
times=()
phase() {  # phase NAME COMMAND...: runs it and keeps its time
  local name="$1" start=$SECONDS
  shift
  "$@"
  times+=("$(printf '%-26s %5d s' "$name" $((SECONDS - start)))")
  echo "test.sh: ${times[-1]}"
}
phase "setup (apt)" bash tools/setup.sh
phase "formatting" bash tools/check_format.sh
phase "build (RelWithDebInfo)" bash tools/build.sh
phase "tests" ctest --test-dir build -j "$(nproc)" --output-on-failure --timeout 600
if [ "${IGNAV_SANITIZE:-1}" != 0 ]; then
  phase "sanitizers and fuzzers" bash tools/sanitize.sh "${IGNAV_FUZZ_SECONDS:-30}"
fi
echo "test.sh: the phases' times:"
printf '  %s\n' "${times[@]}"
