#!/usr/bin/env python3
"""A lossy, slow link in user space: what `tc qdisc ... netem loss 5% delay 50ms 20ms` does, for
kernels without sch_netem (this project's machines: "Specified qdisc kind is unknown").

It owns a TUN device in the router namespace of tests/network/netns.sh. Policy routing there sends
every packet that arrives from a host's veth into the TUN device; this program reads it, drops it
with probability --loss, otherwise holds it for a delay drawn uniformly from
[delay - jitter, delay + jitter] ms (netem's default jitter distribution, so packets reorder as
they do under netem) and writes it back, and the kernel forwards it by its destination. Each packet
crossing the router is impaired once, as netem on the sender's egress would. The random stream is
seeded: a run is repeatable packet for packet given the same traffic.

  lossy_router.py --tun NAME [--loss 0.05] [--delay-ms 50] [--jitter-ms 20] [--seed 1]
                  [--stats FILE]

Prints "lossy_router ready" once the device exists. On SIGTERM writes its counts (packets in,
dropped, forwarded, bytes) as JSON to --stats and exits 0.
"""
import argparse
import fcntl
import heapq
import json
import os
import random
import select
import signal
import struct
import sys
import time

TUNSETIFF = 0x400454CA
IFF_TUN = 0x0001
IFF_NO_PI = 0x1000


def open_tun(name):
    fd = os.open("/dev/net/tun", os.O_RDWR | os.O_NONBLOCK)
    fcntl.ioctl(fd, TUNSETIFF, struct.pack("16sH", name.encode(), IFF_TUN | IFF_NO_PI))
    return fd


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tun", required=True)
    ap.add_argument("--loss", type=float, default=0.05)
    ap.add_argument("--delay-ms", type=float, default=50.0)
    ap.add_argument("--jitter-ms", type=float, default=20.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--stats")
    a = ap.parse_args()
    if not 0.0 <= a.loss < 1.0:
        sys.exit("lossy_router: --loss must be within [0, 1), got %r" % a.loss)
    if a.delay_ms < 0 or a.jitter_ms < 0 or a.jitter_ms > a.delay_ms:
        sys.exit("lossy_router: need 0 <= --jitter-ms <= --delay-ms")

    fd = open_tun(a.tun)
    rng = random.Random(a.seed)
    held = []  # (due monotonic s, sequence, packet): a heap by due time
    counts = {"in": 0, "dropped": 0, "forwarded": 0, "bytes_in": 0}
    seq = 0
    running = True

    def stop(*_):
        nonlocal running
        running = False

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    print("lossy_router ready tun=%s loss=%.3f delay=%.1f±%.1f ms" %
          (a.tun, a.loss, a.delay_ms, a.jitter_ms), flush=True)

    while running:
        now = time.monotonic()
        while held and held[0][0] <= now:
            _, _, packet = heapq.heappop(held)
            try:
                os.write(fd, packet)
                counts["forwarded"] += 1
            except OSError:
                counts["dropped"] += 1  # the kernel refused it (device going down)
        timeout = max(0.0, held[0][0] - now) if held else 0.2
        try:
            ready, _, _ = select.select([fd], [], [], timeout)
        except InterruptedError:
            continue
        if not ready:
            continue
        while True:  # drain what is queued now
            try:
                packet = os.read(fd, 65536)
            except BlockingIOError:
                break
            counts["in"] += 1
            counts["bytes_in"] += len(packet)
            if rng.random() < a.loss:
                counts["dropped"] += 1
                continue
            delay_s = (a.delay_ms + rng.uniform(-a.jitter_ms, a.jitter_ms)) / 1000.0
            seq += 1
            heapq.heappush(held, (time.monotonic() + delay_s, seq, packet))

    if a.stats:
        with open(a.stats, "w") as f:
            json.dump(counts, f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
