#!/usr/bin/env bash
# Commands answered while targets that fill a structure are proposed and accepted (issue 41):
# see bench_proposals.cpp.
#   tools/bench/bench_proposals.sh [ROUNDS] [SPACING_MM]   (default 5 rounds, 8 mm)
#   tools/bench/bench_proposals.sh ROUNDS "strength=0.6" plan_seeds   (seed plans, issue 42)
# IGNAV_BENCH_DOMAIN (default 97): the server's DDS domain.
set -euo pipefail
cd "$(dirname "$0")/../.."
source tools/bench/bench_server.sh
startBenchServer proposals 97
build/tools/bench/bench_proposals "$domain" "$xml" "${1:-5}" "${2:-8}" "${3:-propose_targets}"
stopBenchServer
