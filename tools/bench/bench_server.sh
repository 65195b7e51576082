# Sourced by the benches that talk to a running server: starts ignav-server on loopback in a
# work folder of its own and stops it (and removes the folder) when the bench's shell exits.
#   startBenchServer NAME DEFAULT_DOMAIN   sets $xml, $domain, $work (the session folder), $pid;
# IGNAV_BENCH_DOMAIN overrides the domain.
startBenchServer() {
  xml=configs/dds/loopback.xml
  domain=${IGNAV_BENCH_DOMAIN:-$2}
  mkdir -p out/bench
  work=$(mktemp -d "$PWD/out/bench/$1.XXXXXX")
  build/server/ignav-server --config configs/server.yaml --domain "$domain" \
    --session-dir "$work/session" --insecure --dds-config "$xml" > "$work.ready" 2> "$work.log" &
  pid=$!
  trap 'kill $pid 2>/dev/null || true; rm -rf "$work" "$work.ready" "$work.log"' EXIT
  for _ in $(seq 100); do grep -q ready "$work.ready" 2>/dev/null && break; sleep 0.1; done
  echo "ignav-server on domain $domain ($(nproc) cores, $(uname -m)):"
}

stopBenchServer() {
  kill -TERM "$pid"
  wait "$pid" || true
}
