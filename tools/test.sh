#!/usr/bin/env bash
# The README's test command: install dependencies, build, run every test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
bash tools/build.sh
ctest --test-dir build -j "$(nproc)" --output-on-failure --timeout 600
