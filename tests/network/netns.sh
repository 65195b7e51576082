# Hosts in network namespaces, for the network tests and benches (sourced, not run):
#   source tests/network/netns.sh
#   netns_routed TAG NET_B HOST...   one namespace per host, each in its own subnet
#                                    10.NET_B.<k>.0/24 (the host .2 on its eth0, the router .1),
#                                    all joined by a router namespace TAG-router
#   netns_impair LOSS DELAY_MS JITTER_MS
#                                    from now on every packet between two hosts crosses
#                                    lossy_router.py (netem's loss and delay, in user space)
#   netns_impair_stop                stops it; its counts are in $work/router.json
#   on HOST CMD...                   runs CMD on HOST
#   addr_of HOST                     the host's address
#   wait_for FILE PATTERN WHAT [S]   until FILE has a line matching PATTERN within S seconds (30)
#   netns_cleanup                    kills every process in the namespaces, removes them
# Nothing outside the namespaces is ever a target. Callers set a trap on EXIT that calls
# netns_cleanup, and define fail().
netns_tag=""
netns_hosts=()
netns_router_pid=""
declare -A netns_addr

on() {
  local h="$1"
  shift
  ip netns exec "$netns_tag-$h" "$@"
}
addr_of() { echo "${netns_addr[$1]}"; }

wait_for() {
  for _ in $(seq $((${4:-30} * 10))); do grep -q "$2" "$1" 2>/dev/null && return 0; sleep 0.1; done
  cat "$1" "${1%.out}.log" 2>/dev/null >&2 || true
  fail "$3 did not start"
}

netns_routed() {
  netns_tag="$1"
  local b="$2"
  shift 2
  netns_hosts=("$@")
  local r="$netns_tag-router"
  ip netns add "$r"
  ip -n "$r" link set lo up
  ip netns exec "$r" sysctl -qw net.ipv4.ip_forward=1 net.ipv4.conf.all.rp_filter=0 \
    net.ipv4.conf.default.rp_filter=0
  local k=1
  for h in "${netns_hosts[@]}"; do
    local ns="$netns_tag-$h"
    ip netns add "$ns"
    ip link add eth0 netns "$ns" type veth peer name "$h" netns "$r"
    ip -n "$ns" addr add "10.$b.$k.2/24" dev eth0
    ip -n "$ns" link set eth0 up
    ip -n "$ns" link set lo up
    ip -n "$ns" route add default via "10.$b.$k.1"
    ip -n "$r" addr add "10.$b.$k.1/24" dev "$h"
    ip -n "$r" link set "$h" up
    netns_addr[$h]="10.$b.$k.2"
    k=$((k + 1))
  done
}

# The router's TUN device takes every packet that comes in from a host (policy routing, table
# 100); what lossy_router.py writes back comes in on the TUN device and is routed by the main
# table to its host.
netns_impair() {
  local r="$netns_tag-router" here
  here="$(dirname "${BASH_SOURCE[0]}")"
  ip netns exec "$r" python3 "$here/lossy_router.py" --tun impair0 --loss "$1" --delay-ms "$2" \
    --jitter-ms "$3" --stats "$work/router.json" >"$work/router.out" 2>&1 &
  netns_router_pid=$!
  wait_for "$work/router.out" "lossy_router ready" "the lossy router"
  ip -n "$r" link set impair0 up
  ip netns exec "$r" sysctl -qw net.ipv4.conf.impair0.rp_filter=0
  ip -n "$r" route add default dev impair0 table 100
  for h in "${netns_hosts[@]}"; do ip -n "$r" rule add iif "$h" lookup 100; done
}

# Stops the lossy router; its counts (packets in, dropped, forwarded) are then in $work/router.json.
netns_impair_stop() {
  kill -TERM "$netns_router_pid" 2>/dev/null || true
  for _ in $(seq 50); do [ -s "$work/router.json" ] && return 0; sleep 0.1; done
  fail "the lossy router did not report"
}

netns_cleanup() {
  [ -n "$netns_tag" ] || return 0
  local all=("${netns_hosts[@]}" router)
  for h in "${all[@]}"; do ip netns pids "$netns_tag-$h" 2>/dev/null | xargs -r kill 2>/dev/null || true; done
  sleep 0.5
  for h in "${all[@]}"; do ip netns pids "$netns_tag-$h" 2>/dev/null | xargs -r kill -9 2>/dev/null || true; done
  for h in "${all[@]}"; do ip netns del "$netns_tag-$h" 2>/dev/null || true; done
}
