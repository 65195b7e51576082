#!/usr/bin/env bash
# Load and soak of ignav-server over Cyclone DDS on loopback (docs/RELIABILITY.md).
#   tools/bench/bench_load.sh load [CLIENTS=20] [SECONDS=120] [RATE_PER_CLIENT=10] [SLICE_PERCENT=10]
#   tools/bench/bench_load.sh soak [CYCLES=60] [TARGETS_PER_CYCLE=5]
# SESSION_PARENT (env, default out/bench) holds the session folder; /dev/shm takes the journal's
# fsync off disk. The server runs the simulated controller, fast (--controller-speed 40000).
# IGNAV_BENCH_DOMAIN (default 92): the DDS domain.
set -euo pipefail
cd "$(dirname "$0")/../.."
mode=${1:-load}
parent=${SESSION_PARENT:-out/bench}
xml=configs/dds/loopback.xml
domain=${IGNAV_BENCH_DOMAIN:-92}
mkdir -p "$parent"
session=$(mktemp -d "$parent/load.XXXXXX")
build/server/ignav-server --config configs/server.yaml --domain $domain --session-dir "$session" \
  --insecure --controller-speed 40000 > "$session.ready" 2> "$session.log" &
pid=$!
trap 'kill $pid 2>/dev/null || true; rm -rf "$session" "$session.ready" "$session.log"' EXIT
for _ in $(seq 100); do grep -q ready "$session.ready" 2>/dev/null && break; sleep 0.1; done
echo "ignav-server pid $pid, session in $parent, $(nproc) cores"
rc=0
case "$mode" in
  load)
    build/tools/bench/bench_load --domain $domain --dds-config "$xml" --server-pid $pid \
      --clients "${2:-20}" --seconds "${3:-120}" --rate "${4:-10}" --slices "${5:-10}" || rc=$?
    ;;
  soak)
    build/tools/bench/bench_load --domain $domain --dds-config "$xml" --server-pid $pid \
      --soak "${2:-60}" --targets-per-cycle "${3:-5}" || rc=$?
    ;;
  *)
    echo "usage: $0 load|soak ..." >&2
    exit 2
    ;;
esac
kill -TERM $pid
wait $pid || { echo "ignav-server exited with $?"; rc=1; }
# grep -c exits 1 when it counts none: a clean run is not a failure (pipefail).
echo "server log lines with error/critical: $(grep -c 'critical\|error' "$session.log" || true)"
exit $rc
