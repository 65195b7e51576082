#!/usr/bin/env bash
# Three hosts on one network, made by this test in network namespaces (docs/DEPLOYMENT.md):
#   robot    ignav-server on the DMC emulator (its Galil on the host's own loopback)
#   planning ignavctl: the demo's scripted session (configs/demo/plan.yaml) end to end, then
#            ignavctl doctor
#   viewer   ignav-web, and headless Chromium loading it through the gateway
# joined by a bridge in a fourth namespace (the switch), 10.77.<n>.0/24, DDS domain 197, the
# site-multicast configuration on each host's eth0, DDS Security on with the test PKI. Nothing
# outside the namespaces is ever a target; they are removed at the end whatever happens.
# Needs root (ip netns); exits 77 (skipped) without it.
#
#   tests/network/hosts_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build="$(cd "$1" && pwd)"
source="$(cd "$2" && pwd)"
tag="ig$$"
hosts=(robot plan view)
switch="$tag-switch"
work="$(mktemp -d)"
fail() { echo "hosts_test: $*" >&2; exit 1; }
# on, wait_for, and netns_cleanup: every process in the namespaces goes with them (a process left
# behind would keep the namespace, and any lock the test runner holds, alive).
. "$source/tests/network/netns.sh"
netns_tag="$tag"
netns_hosts=("${hosts[@]}")
cleanup() {
  netns_cleanup
  ip netns del "$switch" 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT

if [ "$(id -u)" -ne 0 ] || ! ip netns add "$switch" 2>/dev/null; then
  echo "hosts_test: skipped: network namespaces need root (ip netns add)"
  exit 77
fi
net="10.77.$(( $$ % 200 + 20 ))"
ip -n "$switch" link add br0 type bridge
ip -n "$switch" link set br0 up
n=1
for h in "${hosts[@]}"; do
  ns="$tag-$h"
  ip netns add "$ns"
  ip link add eth0 netns "$ns" type veth peer name "$h" netns "$switch"
  ip -n "$switch" link set "$h" master br0 up
  ip -n "$ns" addr add "$net.$n/24" dev eth0
  ip -n "$ns" link set eth0 up
  ip -n "$ns" link set lo up
  n=$((n + 1))
done

"$source/configs/security/make-test-pki.sh" "$work/pki" >/dev/null
dds=(--domain 197 --dds-config site-multicast --dds-interface eth0)

# The robot host: its motor controller, then the server on it.
on robot "$build/tools/dmc-emulator/dmc-emulator" --port 0 >"$work/dmc.out" 2>&1 &
wait_for "$work/dmc.out" "listening on" "the DMC emulator"
dmc_port="$(sed -n 's/.*listening on 127.0.0.1:\([0-9]*\).*/\1/p' "$work/dmc.out")"
on robot "$build/server/ignav-server" --config "$source/configs/server.yaml" "${dds[@]}" \
  --identity "$work/pki/service" --session-dir "$work/session" --no-igtl \
  --controller "galil:127.0.0.1:$dmc_port" --controller-speed 40000 \
  >"$work/server.out" 2>"$work/server.log" &
wait_for "$work/server.out" "ignav-server ready" "ignav-server"

# The viewer host: the gateway finds the robot over the network, a browser loads it.
on view "$build/tools/ignav-web/ignav-web" "${dds[@]}" --identity "$work/pki/viewer" \
  --client-id web-viewer --port 0 >"$work/web.out" 2>"$work/web.log" &
wait_for "$work/web.out" "ignav-web ready" "ignav-web"
grep -q "robot=robot-1" "$work/web.out" || fail "the gateway did not find robot-1: $(cat "$work/web.out")"
web_url="$(sed -n 's/.*url=\([^ ]*\).*/\1/p' "$work/web.out")"

# The planning host: the whole scripted session, every motion approved as shown.
ctl=("$build/tools/ignavctl/ignavctl" "${dds[@]}" --identity "$work/pki/approver"
  --client-id operator --wait-server 20)
(cd "$source" && on plan "${ctl[@]}" run configs/demo/plan.yaml --out-dir "$work/plan") \
  >"$work/plan.out" 2>&1 || { cat "$work/plan.out" >&2; fail "the scripted session failed"; }
on plan "${ctl[@]}" --json status >"$work/status.json" 2>/dev/null
grep -q '"phase": "done"' "$work/status.json" || fail "the session did not end done"

# The browser, on the viewer host, sees the finished session through the gateway.
if command -v chromium >/dev/null; then
  on view node "$source/tools/ignav-web/screenshot.mjs" --url "$web_url" \
    --out "$work/viewer.png" --chromium "$(command -v chromium)" >"$work/shot.out" 2>&1 ||
    { cat "$work/shot.out" >&2; fail "the browser on the viewer host"; }
  [ "$(stat -c %s "$work/viewer.png")" -gt 20000 ] || fail "the viewer's screenshot is empty"
fi

# doctor, from the planning host: the server and the gateway by name, every check passed.
on plan "${ctl[@]}" --json doctor --seconds 2 >"$work/doctor.json" 2>"$work/doctor.err" ||
  { cat "$work/doctor.json" "$work/doctor.err" >&2; fail "doctor found a problem"; }
grep -q '"name": "ignav-server robot-1@' "$work/doctor.json" || fail "doctor did not see the server"
grep -q '"name": "ignav-web web-viewer@' "$work/doctor.json" || fail "doctor did not see the gateway"
grep -q '"subject": "CN=service,O=ignav,C=NL"' "$work/doctor.json" ||
  fail "doctor did not see the server's certificate"

# The journal, re-derived offline: every motion after its approval, every record reproduced.
"$build/tools/ignav-plan/ignav-plan" replay "$work/session" \
  --robot "$source/configs/robots/torabi2014.yaml" --verify >"$work/replay.out" 2>&1 ||
  { cat "$work/replay.out" >&2; fail "the recorded session does not re-derive"; }
approvals="$(grep -c '"input":"approve"' "$work/session/journal.jsonl" || true)"
[ "$approvals" -ge 1 ] || fail "no approval in the journal"
segments="$(grep -c '"input":"segment_done"' "$work/session/journal.jsonl" || true)"
# What doctor measured across the bridge, for the record.
across="$(python3 -c 'import json,sys; r=json.load(open(sys.argv[1]))["robots"][0]
print("round trip median %.2f ms, max %.2f ms; clock offset %+.1f ms" % (r["round_trip_ms"]["median"],
      r["round_trip_ms"]["max"], r.get("clock_offset_ms", float("nan"))))' "$work/doctor.json")"
echo "hosts_test: ok (3 hosts on $net.0/24, DDS Security on; $approvals approvals, $segments" \
  "motion segments; the browser, doctor and the offline check pass; planning -> robot: $across)"
