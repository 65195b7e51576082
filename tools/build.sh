#!/usr/bin/env bash
# Configures and builds ignav into build/ (Release-with-debug-info, Ninja, both cores).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build -j "$(nproc)"
