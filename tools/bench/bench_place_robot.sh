#!/usr/bin/env bash
# Commands answered while the robot is placed (issue 41): see bench_place_robot.cpp.
#   tools/bench/bench_place_robot.sh [ROUNDS]   (default 3)
# IGNAV_BENCH_DOMAIN (default 96): the server's DDS domain.
set -euo pipefail
cd "$(dirname "$0")/../.."
source tools/bench/bench_server.sh
startBenchServer place_robot 96
build/tools/bench/bench_place_robot "$domain" "$xml" "${1:-3}"
stopBenchServer
