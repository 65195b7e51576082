#!/usr/bin/env bash
# Where ignav-server's memory goes under load (docs/PERFORMANCE.md, "Many clients at once").
#   tools/bench/bench_memory.sh [SECONDS=600] [glibc|jemalloc] [ROUNDS=1]
# Runs the server (simulated controller, session on /dev/shm) under bench_load's 20 clients x 10
# commands/s with 10 % slices, ROUNDS times SECONDS against the same server (each round removes
# the targets it made), and prints every minute, and once idle after each round:
#   - VmRSS and RssAnon from /proc;
#   - with glibc's allocator, what malloc_info(3) says (tools/bench/malloc_probe.cpp, preloaded,
#     writes it every 10 s from inside the server): the bytes its arenas hold, how many of them
#     are free, and the rest, in use by the program. In use growing is a leak or a growing cache;
#     arenas growing while in use stays is the allocator's fragmentation. What a round leaves in
#     use once idle, round after round, tells a leak (it adds up) from buffers that grew to a
#     high-water mark (it does not).
# IGNAV_MALLOC_PROBE_TRIM=1: the probe also calls malloc_trim(0) before each report and the bench
# prints how long it took (it holds each arena's lock while it runs): what RSS would be if glibc
# gave its free pages back.
# `jemalloc` preloads Debian's libjemalloc2 (apt-get install libjemalloc2) into the server instead.
# IGNAV_BENCH_DOMAIN (default 97): the DDS domain.
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${1:-600}
allocator=${2:-glibc}
rounds=${3:-1}
domain=${IGNAV_BENCH_DOMAIN:-97}
work=$(mktemp -d /dev/shm/bench_memory.XXXXXX)
pid=
trap 'kill $pid 2>/dev/null || true; rm -rf "$work"' EXIT
case "$allocator" in
  glibc) preload=(env "LD_PRELOAD=$PWD/build/tools/bench/malloc_probe.so"
    "IGNAV_MALLOC_PROBE_OUT=$work/info.xml" IGNAV_MALLOC_PROBE_S=10 "IGNAV_MALLOC_PROBE_TRIM=${IGNAV_MALLOC_PROBE_TRIM:-0}") ;;
  jemalloc)
    lib=$(ls /usr/lib/*-linux-gnu/libjemalloc.so.2 2>/dev/null | head -1)
    [ -n "$lib" ] || { echo "bench_memory: libjemalloc2 is not installed" >&2; exit 2; }
    preload=(env "LD_PRELOAD=$lib")
    ;;
  *)
    echo "usage: $0 [SECONDS] [glibc|jemalloc]" >&2
    exit 2
    ;;
esac
"${preload[@]}" build/server/ignav-server --config configs/server.yaml --domain "$domain" \
  --session-dir "$work/session" --insecure --controller-speed 40000 \
  >"$work/server.out" 2>"$work/server.log" &
pid=$!
for _ in $(seq 100); do grep -q ready "$work/server.out" 2>/dev/null && break; sleep 0.1; done

# malloc_info's totals (after the last arena): system bytes, free bytes (fast + rest), mmapped.
arenas() {
  python3 - "$work/info.xml" <<'EOF'
import re, sys
try:
    body = open(sys.argv[1]).read()
    tail = body[body.rindex('</heap>'):]
    total = {k: int(v) for k, v in re.findall(r'<total type="(\w+)" count="\d+" size="(\d+)"/>', tail)}
    system = int(re.search(r'<system type="current" size="(\d+)"/>', tail).group(1))
    free = total.get('fast', 0) + total.get('rest', 0)
    print(f"{system / 2**20:.2f} {free / 2**20:.2f} {(system - free + total.get('mmap', 0)) / 2**20:.2f}")
except (OSError, ValueError, AttributeError):
    print("- - -")
EOF
}
kib() { awk -v k="$1" '$1 == k ":" { printf "%.2f", $2 / 1024 }' /proc/$pid/status; }

echo "ignav-server pid $pid ($allocator), $(nproc) cores, load for $seconds s x $rounds"
printf '%6s %10s %12s %14s %18s %16s\n' min "RSS MiB" "RssAnon MiB" "arenas MiB" "free in them MiB" "in use MiB"
t=0 next=0
for round in $(seq "$rounds"); do
  build/tools/bench/bench_load --domain "$domain" --dds-config configs/dds/loopback.xml \
    --server-pid $pid --clients 20 --seconds "$seconds" --rate 10 --slices 10 >"$work/load.out" 2>&1 &
  load=$!
  while kill -0 $load 2>/dev/null; do
    if [ "$t" -ge "$next" ]; then
      next=$((next + 60))
      read -r sys free used < <(arenas)
      printf '%6d %10s %12s %14s %18s %16s\n' $((t / 60)) "$(kib VmRSS)" "$(kib RssAnon)" "$sys" "$free" "$used"
    fi
    sleep 5
    t=$((t + 5))
  done
  wait $load || { cat "$work/load.out"; exit 1; }
  sleep 11  # the probe's next report, taken after the load
  t=$((t + 11))
  read -r sys free used < <(arenas)
  printf '%6s %10s %12s %14s %18s %16s\n' "idle$round" "$(kib VmRSS)" "$(kib RssAnon)" "$sys" "$free" "$used"
  grep -E '^(throughput|replies|server)' "$work/load.out"
done
{ grep -h "^malloc_trim" "$work/server.log" || true; } | sort -k2 -n | awk '{a[NR]=$2} END{if(NR) printf "malloc_trim: %d calls, median %.3f ms, max %.3f ms\n", NR, a[int((NR+1)/2)], a[NR]}'
