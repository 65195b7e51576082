#!/usr/bin/env bash
# Commands answered while the patient's structures load (issue 41): see bench_structures.cpp.
#   tools/bench/bench_structures.sh [ROUNDS]   (default 10)
# IGNAV_BENCH_DOMAIN (default 98): the server's DDS domain.
set -euo pipefail
cd "$(dirname "$0")/../.."
source tools/bench/bench_server.sh
startBenchServer structures 98
build/tools/bench/bench_structures "$domain" "$xml" "$work" "${1:-10}"
stopBenchServer
