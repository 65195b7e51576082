#!/usr/bin/env python3
"""systemd's notify protocol against a real ignav-server, without systemd: a datagram socket as
NOTIFY_SOCKET, WATCHDOG_USEC asked for; the server must say READY=1 once it serves (after its
readiness line), WATCHDOG=1 at least every half period while it runs, and STOPPING=1 on SIGTERM
before it exits 0.

  notify_check.py SERVER_EXE CONFIG DOMAIN SESSION_DIR
"""
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time


def main():
    exe, config, domain, session_dir = sys.argv[1:5]
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "notify")
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        sock.bind(path)
        sock.settimeout(0.1)
        env = dict(os.environ, NOTIFY_SOCKET=path, WATCHDOG_USEC="1000000")
        server = subprocess.Popen(
            [exe, "--config", config, "--domain", domain, "--session-dir", session_dir,
             "--no-igtl", "--robot-id-check-ms", "100"],
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env, text=True)
        messages = []  # (seconds since start, message)
        start = time.monotonic()
        ready_line = server.stdout.readline()
        ready_line_at = time.monotonic() - start
        if "ignav-server ready" not in ready_line:
            server.kill()
            sys.exit(f"no readiness line: {ready_line!r}")

        def drain(until):
            while time.monotonic() < until:
                try:
                    data = sock.recv(4096).decode()
                except socket.timeout:
                    continue
                messages.append((time.monotonic() - start, data))

        drain(time.monotonic() + 3.0)
        server.send_signal(signal.SIGTERM)
        code = server.wait(timeout=30)
        drain(time.monotonic() + 0.3)

    kinds = [m.split("\n")[0] for _, m in messages]
    problems = []
    if code != 0:
        problems.append(f"exit code {code} after SIGTERM")
    if not kinds or kinds[0] != "READY=1":
        problems.append(f"the first message is not READY=1: {kinds[:3]}")
    elif "STATUS=robot robot-1 on DDS domain" not in messages[0][1]:
        problems.append(f"READY without the status line: {messages[0][1]!r}")
    if messages and messages[0][0] + 0.05 < ready_line_at:
        problems.append("READY=1 came before the readiness line")
    pings = [t for (t, _), k in zip(messages, kinds) if k == "WATCHDOG=1"]
    if len(pings) < 4:  # 3 s at one ping per half period (0.5 s): about 5
        problems.append(f"only {len(pings)} WATCHDOG=1 in 3 s with WATCHDOG_USEC=1000000")
    gaps = [b - a for a, b in zip(pings, pings[1:])]
    if gaps and max(gaps) > 1.0:
        problems.append(f"a watchdog gap of {max(gaps):.3f} s, longer than the period (1 s)")
    if "STOPPING=1" not in kinds or kinds[-1] != "STOPPING=1":
        problems.append(f"no STOPPING=1 at the end: {kinds[-3:]}")
    if problems:
        sys.exit("notify_check: " + "; ".join(problems))
    print(f"notify_check: READY=1, {len(pings)} WATCHDOG=1 (largest gap "
          f"{max(gaps) if gaps else 0:.3f} s), STOPPING=1, exit 0")


if __name__ == "__main__":
    main()
