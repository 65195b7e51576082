#!/usr/bin/env bash
# Round trips through ignav-server's OpenIGTLink bridge on loopback (docs/PERFORMANCE.md).
#   tools/bench/bench_igtl.sh [ROUNDS] [SESSION_PARENT] [REVISION=slicer|brp2013]
# IGNAV_BENCH_DOMAIN (default 92): the DDS domain; the bridge takes a free port.
# SESSION_PARENT defaults to a disk folder; pass /dev/shm to take the journal's fsync off disk.
set -euo pipefail
cd "$(dirname "$0")/../.."
rounds=${1:-1000}
parent=${2:-out/bench}
revision=${3:-slicer}
domain=${IGNAV_BENCH_DOMAIN:-92}
mkdir -p "$parent"
session=$(mktemp -d "$parent/igtl.XXXXXX")
build/server/ignav-server --config configs/server.yaml --domain "$domain" --session-dir "$session" \
  --insecure --igtl-port 0 --igtl-protocol "$revision" > "$session.ready" 2> "$session.log" &
pid=$!
trap 'kill $pid 2>/dev/null || true; rm -rf "$session" "$session.ready" "$session.log"' EXIT
for _ in $(seq 100); do grep -q ready "$session.ready" 2>/dev/null && break; sleep 0.1; done
port=$(grep -o 'igtl_port=[0-9]*' "$session.ready" | cut -d= -f2)
echo "ignav-server OpenIGTLink bridge on port $port, revision $revision (session in $parent):"
build/tools/bench/bench_igtl "$port" "$rounds" "$revision"
kill -TERM $pid; wait $pid || true
