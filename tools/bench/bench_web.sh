#!/usr/bin/env bash
# Round trips through the web viewer's gateway (bench_web), with ignav-server and ignav-web on
# loopback; then the same server round trips without the gateway (bench_latency) for comparison.
#   tools/bench/bench_web.sh [ROUNDS] [SESSION_PARENT]
# IGNAV_BENCH_DOMAIN (default 94): the DDS domain; the gateway takes a free port.
set -euo pipefail
cd "$(dirname "$0")/../.."
rounds=${1:-500}
parent=${2:-out/bench}
xml=configs/dds/loopback.xml
domain=${IGNAV_BENCH_DOMAIN:-94}
mkdir -p "$parent"
session=$(mktemp -d "$parent/web.XXXXXX")
build/server/ignav-server --config configs/server.yaml --domain "$domain" --session-dir "$session" \
  --insecure > "$session.ready" 2> "$session.log" &
server=$!
build/tools/ignav-web/ignav-web --dds-config "$xml" --domain "$domain" --port 0 --client-id operator \
  > "$session.web" 2> "$session.weblog" &
web=$!
trap 'kill $server $web 2>/dev/null || true; rm -rf "$session" "$session".*' EXIT
for _ in $(seq 100); do grep -q ready "$session.ready" 2>/dev/null && grep -q ready "$session.web" && break; sleep 0.1; done
port=$(sed -n 's/.*url=http:\/\/[^:]*:\([0-9]*\)\/.*/\1/p' "$session.web")
echo "through ignav-web (port $port, session in $parent):"
build/tools/bench/bench_web "$port" "$rounds"
kill -TERM $web $server; wait $web $server || true
