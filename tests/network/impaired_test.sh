#!/usr/bin/env bash
# The scripted session across three hosts on a network that drops and delays packets
# (docs/DEPLOYMENT.md, issue 24): 5 % loss and 50 ± 20 ms on every packet between two hosts
# (tests/network/lossy_router.py: netem's loss and delay in user space, as this machine's kernel has
# no sch_netem), each host in a subnet of its own behind a router namespace, site-unicast with
# each host naming the others, DDS Security on.
#   robot    the DMC emulator (on the host's loopback) and ignav-server on it
#   planning ignavctl --json run configs/demo/plan.yaml (plan, approve, move to every target)
#   viewer   net_probe watch: every reply on the wire, and the state as a viewer mirrors it
# Passes when, under that loss and delay:
#   - the session ends done;
#   - every command is answered exactly once: each (client, request) the viewer saw on the reply
#     topic once, and each reply the script got is one of them, alike;
#   - nothing acknowledged is lost: every accepted command that changes the session has exactly
#     one journal record with its request id and revision, and the journal holds nothing else
#     from the script;
#   - state converges: the viewer's mirror reaches the journal's last revision, phase done, every
#     target reached;
#   - the approval invariant holds: the journal re-derives offline (every motion after its
#     approval), and the router really dropped and delayed (ping's round trip, its counts).
# Needs root and /dev/net/tun; exits 77 (skipped) without them.
#
#   tests/network/impaired_test.sh BUILD_DIR SOURCE_DIR [LOSS=0.05] [DELAY_MS=50] [JITTER_MS=20]
set -euo pipefail
build="$(cd "$1" && pwd)"
source="$(cd "$2" && pwd)"
loss="${3:-0.05}" delay_ms="${4:-50}" jitter_ms="${5:-20}"
work="$(mktemp -d)"
fail() {
  echo "impaired_test: $*" >&2
  exit 1
}
# shellcheck source=netns.sh
. "$source/tests/network/netns.sh"
cleanup() {
  netns_cleanup
  [ -n "${IGNAV_KEEP_WORK:-}" ] && echo "kept $work" >&2 || rm -rf "$work"
}
trap cleanup EXIT

if [ "$(id -u)" -ne 0 ] || [ ! -c /dev/net/tun ] || ! ip netns add "in$$-probe" 2>/dev/null; then
  echo "impaired_test: skipped: needs root, network namespaces and /dev/net/tun"
  exit 77
fi
ip netns del "in$$-probe"
netns_routed "in$$" "$(($$ % 50 + 150))" robot plan view
netns_impair "$loss" "$delay_ms" "$jitter_ms"
robot="$(addr_of robot)" plan="$(addr_of plan)" view="$(addr_of view)"

# The link is what it claims: a ping crosses the router twice (2 x delay on average).
on plan ping -n -c 40 -i 0.05 -W 1 "$robot" >"$work/ping.out" 2>&1 || true
rtt="$(sed -n 's|.*= [0-9.]*/\([0-9.]*\)/.*|\1|p' "$work/ping.out")"
[ -n "$rtt" ] || fail "no ping answered across the router: $(cat "$work/ping.out")"
python3 - "$rtt" "$delay_ms" <<'EOF' || fail "ping's round trip ${rtt} ms is not 2 x ${delay_ms} ms"
import sys
rtt, delay = float(sys.argv[1]), float(sys.argv[2])
sys.exit(0 if abs(rtt - 2 * delay) <= 0.3 * max(delay, 10) + 2 else 1)
EOF

"$source/configs/security/make-test-pki.sh" "$work/pki" >/dev/null
domain=198
site=(--domain "$domain" --dds-config site-unicast --dds-interface eth0)

on robot "$build/tools/dmc-emulator/dmc-emulator" --port 0 >"$work/dmc.out" 2>&1 &
wait_for "$work/dmc.out" "listening on" "the DMC emulator"
dmc_port="$(sed -n 's/.*listening on 127.0.0.1:\([0-9]*\).*/\1/p' "$work/dmc.out")"
on robot "$build/server/ignav-server" --config "$source/configs/server.yaml" "${site[@]}" \
  --dds-peer "$plan" --dds-peer "$view" --identity "$work/pki/service" \
  --session-dir "$work/session" --no-igtl --controller "galil:127.0.0.1:$dmc_port" \
  --controller-speed 40000 >"$work/server.out" 2>"$work/server.log" &
wait_for "$work/server.out" "ignav-server ready" "ignav-server"

# The viewer host watches the reply topic and mirrors the state from before the first command.
on view "$build/tests/net_probe" "${site[@]}" --dds-peer "$robot" --dds-peer "$plan" \
  --identity "$work/pki/viewer" --client-id watcher --out "$work/watch.json" \
  watch --stop-file "$work/stop" >"$work/watch.out" 2>&1 &
watch_pid=$!
# Up to 30 s each to find the robot, match the server's topics and the reply topic (net_probe).
wait_for "$work/watch.out" "net_probe watch ready" "the viewer's watch" 100

start=$(date +%s.%N)
(cd "$source" && on plan "$build/tools/ignavctl/ignavctl" "${site[@]}" --dds-peer "$robot" \
  --dds-peer "$view" --identity "$work/pki/approver" --client-id operator --wait-server 60 \
  --json run configs/demo/plan.yaml --out-dir "$work/plan") >"$work/plan.out" 2>&1 ||
  { tail -30 "$work/plan.out" >&2; fail "the scripted session failed under loss and delay"; }
elapsed="$(python3 -c "import sys; print('%.1f' % ($(date +%s.%N) - $start))")"

journal="$work/session/journal.jsonl"
python3 -c 'import json,sys; print(json.loads(open(sys.argv[1]).readlines()[-1])["revision"])' \
  "$journal" >"$work/stop"
wait "$watch_pid" || { cat "$work/watch.out" >&2; fail "the viewer's watch failed"; }
netns_impair_stop

# The checks, on the three records: the script's replies, the wire, the journal.
python3 - "$work/plan.out" "$work/watch.json" "$journal" "$work/router.json" <<'EOF' ||
import json, re, sys
plan_out, watch, journal, router = sys.argv[1:]
problems = []
# The script's replies: "<script>: step N <command>: {reply}" (approve: "approve plan P").
script = []
for line in open(plan_out):
    m = re.match(r".*: step (\d+) (\w+)(?: plan \d+)?: (\{.*\})$", line.strip())
    if m:
        script.append((m.group(2), json.loads(m.group(3))))
if len(script) < 10:
    problems.append("only %d replies in the script's output" % len(script))
w = json.load(open(watch))
wire = {}
for r in w["replies"]:
    key = (r["client_id"], r["request_id"])
    wire.setdefault(key, []).append(r)
twice = [k for k, v in wire.items() if len(v) != 1]
if twice:
    problems.append("replies seen more than once on the wire: %s" % twice[:5])
for command, r in script:
    seen = wire.get((r["client_id"], r["request_id"]))
    if not seen:
        problems.append("%s %d: answered to the script but not seen on the wire" %
                        (command, r["request_id"]))
    elif (seen[0]["accepted"], seen[0]["revision"]) != (r["accepted"], r["revision"]):
        problems.append("%s %d: the wire and the script disagree" % (command, r["request_id"]))
ours = {r["request_id"] for _, r in script}
strays = [k for k in wire if k[0] == "operator" and k[1] not in ours]
if strays:
    problems.append("replies to the operator that the script never asked for: %s" % strays[:5])
records = [json.loads(l) for l in open(journal)]
by_request = {}
for rec in records:
    if rec.get("client_id") == "operator":
        by_request.setdefault(rec["request_id"], []).append(rec)
for command, r in script:
    recs = by_request.get(r["request_id"], [])
    changes = r["accepted"] and command not in ("query",)
    if changes and (len(recs) != 1 or recs[0]["revision"] != r["revision"]):
        problems.append("%s %d (accepted, revision %d): journal has %s" %
                        (command, r["request_id"], r["revision"],
                         [x["revision"] for x in recs]))
    if not changes and recs:
        problems.append("%s %d was not accepted or changes nothing, yet is journaled" %
                        (command, r["request_id"]))
extra = set(by_request) - ours
if extra:
    problems.append("journal records from the operator the script never sent: %s" % sorted(extra)[:5])
revisions = [rec["revision"] for rec in records]
if revisions != list(range(1, len(revisions) + 1)):
    problems.append("journal revisions have gaps")
state = w["state"]
if state["workflow"]["revision"] != revisions[-1]:
    problems.append("the viewer's state stopped at revision %d, the journal at %d" %
                    (state["workflow"]["revision"], revisions[-1]))
if state["workflow"]["phase"] != "done":
    problems.append("the viewer's phase is %s, not done" % state["workflow"]["phase"])
statuses = sorted(t["status"] for t in state.get("targets", {}).values())
if not statuses or any(s != "reached" for s in statuses if s != "unreachable"):
    problems.append("the viewer's targets: %s" % statuses)
counts = json.load(open(router))
if counts["dropped"] == 0 or counts["forwarded"] == 0:
    problems.append("the router dropped or forwarded nothing: %s" % counts)
approvals = sum(1 for rec in records if rec["input"] == "approve")
for p in problems:
    print("impaired_test: " + p, file=sys.stderr)
print("%d replies, %d journal records, %d approvals; router: %d packets, %d dropped" %
      (len(script), len(records), approvals, counts["in"], counts["dropped"]))
sys.exit(1 if problems else 0)
EOF
  fail "the records disagree (above)"
summary="$(python3 -c 'import json,sys; c=json.load(open(sys.argv[1])); print(c["in"], c["dropped"])' "$work/router.json")"

# The approval invariant, offline: every record re-derived, every motion after its approval.
"$build/tools/ignav-plan/ignav-plan" replay "$work/session" \
  --robot "$source/configs/robots/torabi2014.yaml" --verify >"$work/replay.out" 2>&1 ||
  { cat "$work/replay.out" >&2; fail "the recorded session does not re-derive"; }
echo "impaired_test: ok (loss $loss, delay $delay_ms ± $jitter_ms ms per crossing, ping round" \
  "trip $rtt ms; the session took $elapsed s; router packets/dropped: $summary)"
