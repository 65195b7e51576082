#!/usr/bin/env bash
# Slice request -> PNG received over DDS (build/tools/bench/bench_slices), against ignav-server on
# the phantom as a 512x512x300 series, on the loopback config; see bench_slices.cpp.
#   tools/bench/bench_slices.sh [ROUNDS=300]
# IGNAV_BENCH_DOMAIN (default 93): the server's DDS domain.
set -euo pipefail
cd "$(dirname "$0")/../.."
rounds=${1:-300}
xml=configs/dds/loopback.xml
domain=${IGNAV_BENCH_DOMAIN:-93}
work=$(mktemp -d /tmp/ignav_slices.XXXXXX)
# --robot: the beads where auto_fiducials finds them, as the server's own phantom has them
build/tools/ignav-plan/ignav-plan phantom "$work/series" --dims 512,512,300 --noise-hu 10 \
  --robot configs/robots/torabi2014.yaml >/dev/null
build/server/ignav-server --config configs/server.yaml --domain "$domain" \
  --session-dir "$work/session" --insecure >"$work/ready" 2>"$work/log" &
pid=$!
trap 'kill $pid 2>/dev/null || true; rm -rf "$work"' EXIT
for _ in $(seq 100); do grep -q ready "$work/ready" 2>/dev/null && break; sleep 0.1; done
build/tools/bench/bench_slices "$domain" "$xml" "$work/series" "$rounds" || { tail -5 "$work/log"; exit 1; }
kill -TERM $pid
wait $pid || true
