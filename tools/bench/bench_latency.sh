#!/usr/bin/env bash
# Command latency of ignav-server next to Cyclone's own ping-pong on the same machine and config.
#   tools/bench/bench_latency.sh [ROUNDS] [SESSION_PARENT] [secure]
# SESSION_PARENT defaults to a disk folder; pass /dev/shm to take the journal's fsync off disk.
# "secure": DDS Security on (a test PKI; service and approver identities), to see its cost.
# IGNAV_BENCH_DOMAIN (default 90): the server's DDS domain; ddsperf runs on the next one up.
# IGNAV_BENCH_PIN: none (default), one (server and client on CPU 0) or across (server on CPU 0,
# client on CPU 1); ddsperf's pong and ping are pinned as the server and the client are.
set -euo pipefail
cd "$(dirname "$0")/../.."
rounds=${1:-2000}
parent=${2:-out/bench}
xml=configs/dds/loopback.xml
domain=${IGNAV_BENCH_DOMAIN:-90}
server_cpu=() client_cpu=()
case "${IGNAV_BENCH_PIN:-none}" in
  none) ;;
  one) server_cpu=(taskset -c 0) client_cpu=(taskset -c 0) ;;
  across) server_cpu=(taskset -c 0) client_cpu=(taskset -c 1) ;;
  *) echo "IGNAV_BENCH_PIN must be none, one or across" >&2; exit 2 ;;
esac
mkdir -p "$parent"
session=$(mktemp -d "$parent/latency.XXXXXX")
server_identity=(--insecure)
client_identity=()
if [ "${3:-}" = secure ]; then
  configs/security/make-test-pki.sh "$session.pki" > /dev/null
  server_identity=(--identity "$session.pki/service")
  client_identity=("$session.pki/approver")
fi
"${server_cpu[@]}" build/server/ignav-server --config configs/server.yaml --domain "$domain" --session-dir "$session" \
  "${server_identity[@]}" > "$session.ready" 2> "$session.log" &
pid=$!
trap 'kill $pid 2>/dev/null || true; rm -rf "$session" "$session.ready" "$session.log" "$session.pki"' EXIT
for _ in $(seq 100); do grep -q ready "$session.ready" 2>/dev/null && break; sleep 0.1; done
echo "ignav-server (session in $parent, $(grep -o 'security=[a-zA-Z]*' "$session.ready"), pinning ${IGNAV_BENCH_PIN:-none}):"
"${client_cpu[@]}" build/tools/bench/bench_latency "$domain" "$xml" "$rounds" "${client_identity[@]}"
kill -TERM $pid; wait $pid || true

echo "ddsperf ping-pong, same config (it prints half the round trip; doubled here):"
export CYCLONEDDS_URI="file://$PWD/$xml"
# Its default answers in a listener, on DDS's receive thread; "waitset" answers on an application
# thread woken by a waitset, as ignav-server and its clients do.
for mode in listener waitset; do
  "${server_cpu[@]}" timeout 12 ddsperf -D 6 -i $((domain + 1)) pong $mode > /dev/null 2>&1 &
  sleep 0.3
  "${client_cpu[@]}" timeout 12 ddsperf -D 5 -i $((domain + 1)) ping $mode 2>&1 | awk -v name="ddsperf round trip ($mode)" '/ 50% /{for(i=1;i<=NF;i++){if($i=="50%")m=$(i+1); if($i=="99%")p=$(i+1)}} END{gsub("us","",m); gsub("us","",p); printf "%-44s median %8.1f us   p99 %8.1f us\n", name, 2*m, 2*p}'
  wait
done
