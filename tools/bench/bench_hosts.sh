#!/usr/bin/env bash
# Command round trip and state propagation across hosts, with N viewers subscribed from another
# host (docs/PERFORMANCE.md, issue 24). Three network namespaces behind a router namespace
# (tests/network/netns.sh): the robot host runs ignav-server (simulated controller), the viewer
# host N viewers (tests/net_probe viewers: each its own participant, a reader of the target topic),
# the planning host the commander (net_probe commander: move_target ROUNDS times, then query).
# site-unicast, DDS Security on. Optionally the link is impaired (lossy_router.py).
#
#   sudo tools/bench/bench_hosts.sh [--viewers 30] [--rounds 100] [--interval-ms 100]
#        [--domain 196] [--impair LOSS,DELAY_MS,JITTER_MS] [--insecure] [--build build]
#
# Prints, in ms (medians, p95, max):
#   command round trip   move_target and query, planning host -> robot host -> planning host
#   state propagation    move_target sent -> the target's sample at a viewer (every viewer, and
#                        the last of the N per move); samples a later move superseded are counted
# Needs root (network namespaces).
set -euo pipefail
cd "$(dirname "$0")/../.."
source_dir="$(pwd)"
viewers=30 rounds=100 interval_ms=100 domain=196 impair="" build=build secure=1
while [ $# -gt 0 ]; do
  case "$1" in
    --viewers) viewers="$2"; shift 2 ;;
    --rounds) rounds="$2"; shift 2 ;;
    --interval-ms) interval_ms="$2"; shift 2 ;;
    --domain) domain="$2"; shift 2 ;;
    --impair) impair="$2"; shift 2 ;;
    --build) build="$2"; shift 2 ;;
    --insecure) secure=0; shift ;;
    *) echo "usage: $0 [--viewers N] [--rounds N] [--interval-ms MS] [--domain D] [--impair LOSS,DELAY,JITTER] [--build DIR]" >&2; exit 2 ;;
  esac
done
build="$(cd "$build" && pwd)"
work="$(mktemp -d)"
fail() {
  echo "bench_hosts: $*" >&2
  exit 1
}
. "$source_dir/tests/network/netns.sh"
cleanup() {
  netns_cleanup
  rm -rf "$work"
}
trap cleanup EXIT
[ "$(id -u)" -eq 0 ] || fail "needs root (network namespaces)"

netns_routed "bh$$" "$(($$ % 50 + 100))" robot plan view
if [ -n "$impair" ]; then
  IFS=, read -r loss delay jitter <<<"$impair"
  netns_impair "$loss" "$delay" "$jitter"
fi
robot="$(addr_of robot)" plan="$(addr_of plan)" view="$(addr_of view)"
"$source_dir/configs/security/make-test-pki.sh" "$work/pki" >/dev/null
site=(--domain "$domain" --dds-config site-unicast --dds-interface eth0)
# Each program's identity (DDS Security), or none.
server_id=(--insecure) viewer_id=() planner_id=()
if [ "$secure" = 1 ]; then
  server_id=(--identity "$work/pki/service")
  viewer_id=(--identity "$work/pki/viewer")
  planner_id=(--identity "$work/pki/approver")
fi

on robot "$build/server/ignav-server" --config configs/server.yaml "${site[@]}" \
  --dds-peer "$plan" --dds-peer "$view" "${server_id[@]}" \
  --session-dir "$work/session" --no-igtl --controller-speed 40000 \
  >"$work/server.out" 2>"$work/server.log" &
wait_for "$work/server.out" "ignav-server ready" "ignav-server"
on view "$build/tests/net_probe" "${site[@]}" --dds-peer "$robot" --dds-peer "$plan" \
  "${viewer_id[@]}" --out "$work/viewers.jsonl" \
  viewers --count "$viewers" --stop-file "$work/stop" >"$work/viewers.out" 2>&1 &
viewers_pid=$!
viewers_started=$(date +%s.%N)
wait_for "$work/viewers.out" "net_probe viewers ready" "the viewers" 240
# How long they took to match, and how many participants were made anew on the way (issue 38).
echo "viewers matched after $(python3 -c "print('%.1f' % ($(date +%s.%N) - $viewers_started))") s: $(grep -o 'made_anew=[0-9]*' "$work/viewers.out")"
on plan "$build/tests/net_probe" "${site[@]}" --dds-peer "$robot" --dds-peer "$view" \
  "${planner_id[@]}" --client-id operator --out "$work/commander.json" \
  commander --rounds "$rounds" --interval-ms "$interval_ms" >"$work/commander.out" 2>&1 ||
  { cat "$work/commander.out" >&2; fail "the commander failed"; }
sleep 2  # the last samples on their way
touch "$work/stop"
wait "$viewers_pid" || { cat "$work/viewers.out" >&2; fail "the viewers failed"; }

python3 - "$work/commander.json" "$work/viewers.jsonl" "$viewers" "${impair:-none}" "$secure" <<'EOF'
import json, sys
commander, viewers_file, n, impair, secure = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4], ("on" if sys.argv[5] == "1" else "off")
c = json.load(open(commander))
arrivals = {}  # x -> {viewer: first arrival}
for line in open(viewers_file):
    a = json.loads(line)
    arrivals.setdefault(a["x"], {}).setdefault(a["viewer"], a["t_ns"])
def stats(v):
    v = sorted(v)
    if not v:
        return "n/a"
    at = lambda q: v[min(len(v) - 1, int(q * len(v)))]
    return "median %7.2f   p95 %7.2f   max %7.2f   (%d)" % (at(0.5), at(0.95), v[-1], len(v))
rtt = [(m["reply_ns"] - m["sent_ns"]) / 1e6 for m in c["moves"]]
every, last, missing = [], [], 0
for m in c["moves"]:
    got = arrivals.get(m["x"], {})
    missing += n - len(got)
    lat = [(t - m["sent_ns"]) / 1e6 for t in got.values()]
    every += lat
    if len(got) == n:
        last.append(max(lat))
print("impairment: %s; DDS Security %s; %d viewers on the viewer host; %d moves" % (impair, secure, n, len(c["moves"])))
print("move_target round trip (ms)              ", stats(rtt))
print("query round trip (ms)                    ", stats(c["queries_ms"]))
print("move sent -> a viewer's sample (ms)      ", stats(every))
print("move sent -> the last of the viewers (ms)", stats(last))
print("samples superseded before they arrived:   %d of %d" % (missing, n * len(c["moves"])))
EOF
