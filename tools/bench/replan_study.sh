#!/usr/bin/env bash
# What re-planning mid-insertion buys through the server (issue 40): see replan_study.cpp.
#   tools/bench/replan_study.sh [N] [WORLD_ARGS...]
# WORLD_ARGS default to the rod-in-tissue world: --world configs/worlds/layered_gel.yaml; a hidden
# extended-bicycle tissue instead: --hidden-tissue agar (configs/tissues.yaml).
# IGNAV_BENCH_DOMAIN (default 93): the server's DDS domain.
set -euo pipefail
cd "$(dirname "$0")/../.."
n=${1:-20}
shift || true
world=("$@")
[ ${#world[@]} -gt 0 ] || world=(--world configs/worlds/layered_gel.yaml)
xml=configs/dds/loopback.xml
domain=${IGNAV_BENCH_DOMAIN:-93}
mkdir -p out/bench
session=$(mktemp -d "$PWD/out/bench/replan_study.XXXXXX")
build/server/ignav-server --config configs/server.yaml --domain "$domain" --session-dir "$session" \
  --insecure --dds-config "$xml" --controller-speed 40000 > "$session.ready" 2> "$session.log" &
pid=$!
trap 'kill $pid 2>/dev/null || true; rm -rf "$session" "$session".*' EXIT
for _ in $(seq 100); do grep -q ready "$session.ready" 2>/dev/null && break; sleep 0.1; done
build/tools/bench/replan_study "$domain" "$xml" "$session" build/tools/ignav-plan/ignav-plan "$n" \
  "${world[@]}"
kill -TERM $pid; wait $pid || true
