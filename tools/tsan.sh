#!/usr/bin/env bash
# ThreadSanitizer over the whole server (docs/RELIABILITY.md): the `tsan` preset builds
# ignav-server, the DMC emulator and the end-to-end suite; the suite then drives the TSan server
# through every e2e test. Any report with a frame of ours fails the test that caused it (a TSan
# server exits 66); reports wholly inside libraries not built with TSan are suppressed
# (tools/tsan.supp says which and why).
#   tools/tsan.sh [GTEST_FILTER=*]
set -euo pipefail
cd "$(dirname "$0")/.."
filter="${1:-*}"
cmake --preset tsan >/dev/null
cmake --build build-tsan -j "$(nproc)" --target e2e_test dmc-emulator
export TSAN_OPTIONS="suppressions=$PWD/tools/tsan.supp:second_deadlock_stack=1:history_size=4"
build-tsan/tests/e2e_test --gtest_filter="$filter"
