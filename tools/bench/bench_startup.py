#!/usr/bin/env python3
"""How long ignav-server takes to serve, fresh and after a crash (issue 38.7).

  tools/bench/bench_startup.py [RUNS] [BUILD_DIR]     (default 10 runs, build/)

Each run starts the server as configs/server.yaml has it (loopback DDS, the simulated controller,
robot_id_check_ms 1000) in a new session folder and measures, from the spawn:
  ready       its readiness line (queries and planning are answered from here on);
  controller  its log's "controller simulated: active" (what reads or moves the robot waits until
              then: the robot-id check);
then kills it (SIGKILL, as a crash) and starts it again on the same folder: the same two times for
the restart, which continues the session from its journal. Prints medians and the spread.
Domain 96 (IGNAV_BENCH_DOMAIN to change it).
"""
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time

runs = int(sys.argv[1]) if len(sys.argv) > 1 else 10
build = sys.argv[2] if len(sys.argv) > 2 else "build"
source = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
server = os.path.join(build, "server", "ignav-server")
domain = os.environ.get("IGNAV_BENCH_DOMAIN", "96")


def start(session, log):
    """Spawns a server on `session`; returns (process, seconds to ready, seconds to controller)."""
    t0 = time.monotonic()
    p = subprocess.Popen(
        [server, "--config", os.path.join(source, "configs", "server.yaml"), "--domain", domain,
         "--no-igtl", "--session-dir", session],
        stdout=subprocess.PIPE, stderr=open(log, "w"), text=True)
    line = p.stdout.readline()
    ready = time.monotonic() - t0
    if "ignav-server ready" not in line:
        p.kill()
        sys.exit("no readiness line: %r (log %s)" % (line, log))
    controller = None
    while time.monotonic() - t0 < 30:
        with open(log) as f:
            if "controller simulated: active" in f.read():
                controller = time.monotonic() - t0
                break
        time.sleep(0.002)
    if controller is None:
        p.kill()
        sys.exit("the controller never started (log %s)" % log)
    return p, ready, controller


def summary(name, values):
    ms = sorted(v * 1000 for v in values)
    print("%-22s median %7.1f ms   min %7.1f   max %7.1f   (%d runs)" %
          (name, statistics.median(ms), ms[0], ms[-1], len(ms)))


fresh_ready, fresh_controller, again_ready, again_controller = [], [], [], []
with tempfile.TemporaryDirectory(prefix="ignav_bench_startup_") as work:
    for i in range(runs):
        session = os.path.join(work, "s%d" % i)
        p, r, c = start(session, session + ".log")
        fresh_ready.append(r)
        fresh_controller.append(c)
        p.send_signal(signal.SIGKILL)
        p.wait()
        p, r, c = start(session, session + ".again.log")
        again_ready.append(r)
        again_controller.append(c)
        p.send_signal(signal.SIGTERM)
        p.wait()
summary("fresh: ready", fresh_ready)
summary("fresh: controller", fresh_controller)
summary("after a crash: ready", again_ready)
summary("after a crash: ctrl", again_controller)
