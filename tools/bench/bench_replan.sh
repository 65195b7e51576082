#!/usr/bin/env bash
# Commands answered while an intermittent CT is searched and a re-aim computed (issue 40): see
# bench_replan.cpp.
#   tools/bench/bench_replan.sh [ROUNDS] [SLICE_MM]   (default 10 rounds, 0.25 mm slices)
# IGNAV_BENCH_DOMAIN (default 92): the server's DDS domain.
set -euo pipefail
cd "$(dirname "$0")/../.."
rounds=${1:-10}
xml=configs/dds/loopback.xml
domain=${IGNAV_BENCH_DOMAIN:-92}
mkdir -p out/bench
session=$(mktemp -d "$PWD/out/bench/replan.XXXXXX")
build/server/ignav-server --config configs/server.yaml --domain "$domain" --session-dir "$session" \
  --insecure --dds-config "$xml" > "$session.ready" 2> "$session.log" &
pid=$!
trap 'kill $pid 2>/dev/null || true; rm -rf "$session" "$session.ready" "$session.log"' EXIT
for _ in $(seq 100); do grep -q ready "$session.ready" 2>/dev/null && break; sleep 0.1; done
echo "ignav-server on domain $domain ($(nproc) cores, $(uname -m)):"
build/tools/bench/bench_replan "$domain" "$xml" "$session" build/tools/ignav-plan/ignav-plan "$rounds" \
  "${2:-0.25}"
kill -TERM $pid; wait $pid || true
