#!/usr/bin/env bash
# The README's test command: install dependencies, build, run every test suite; then the same
# suites under AddressSanitizer + UndefinedBehaviorSanitizer and each fuzzer for a while
# (tools/sanitize.sh). IGNAV_SANITIZE=0 skips that second part (a quicker local run).
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
bash tools/check_format.sh
bash tools/build.sh
ctest --test-dir build -j "$(nproc)" --output-on-failure --timeout 600
if [ "${IGNAV_SANITIZE:-1}" != 0 ]; then
  bash tools/sanitize.sh "${IGNAV_FUZZ_SECONDS:-30}"
fi
