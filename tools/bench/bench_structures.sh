#!/usr/bin/env bash
# Commands answered while the patient's structures load (issue 41): see bench_structures.cpp.
#   tools/bench/bench_structures.sh [ROUNDS]   (default 10)
# IGNAV_BENCH_DOMAIN (default 98): the server's DDS domain.
set -euo pipefail
cd "$(dirname "$0")/../.."
rounds=${1:-10}
xml=configs/dds/loopback.xml
domain=${IGNAV_BENCH_DOMAIN:-98}
mkdir -p out/bench
work=$(mktemp -d "$PWD/out/bench/structures.XXXXXX")
build/server/ignav-server --config configs/server.yaml --domain "$domain" --session-dir "$work/session" \
  --insecure --dds-config "$xml" > "$work.ready" 2> "$work.log" &
pid=$!
trap 'kill $pid 2>/dev/null || true; rm -rf "$work" "$work.ready" "$work.log"' EXIT
for _ in $(seq 100); do grep -q ready "$work.ready" 2>/dev/null && break; sleep 0.1; done
echo "ignav-server on domain $domain ($(nproc) cores, $(uname -m)):"
build/tools/bench/bench_structures "$domain" "$xml" "$work" "$rounds"
kill -TERM $pid; wait $pid || true
