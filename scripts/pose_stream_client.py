#!/usr/bin/env python3
"""Reads lookup-localize's pose stream (--publish tcp://HOST:PORT), printing poses and health.
Standard library only; reconnects while the localiser is down. Usage: HOST PORT"""
import json, socket, sys, time

host, port = sys.argv[1], int(sys.argv[2])
while True:
    try:
        sock = socket.create_connection((host, port), timeout=5)
    except OSError as e:  # the localiser is not up (yet)
        print("waiting for lookup-localize:", e, file=sys.stderr)
        time.sleep(1)
        continue
    sock.settimeout(3)  # a health message comes every second: 3 s of silence = gone
    buffer = b""
    try:
        while data := sock.recv(65536):  # b"": the localiser closed the stream
            *lines, buffer = (buffer + data).split(b"\n")
            for m in map(json.loads, lines):
                if m["type"] == "pose" and m["x"] is not None:
                    print(f"{m['frame']:6} {m['t_image']:.3f} {m['status']:8} x {m['x']:.3f} "
                          f"y {m['y']:.3f} yaw {m['yaw']:.4f} sd_x {m['cov'][0] ** 0.5:.3f} "
                          f"latency {m['latency_ms']:.1f} ms", flush=True)
                elif m["type"] == "pose":
                    print(f"{m['frame']:6} {m['t_image']:.3f} {m['status']:8} {m['reason']}")
                elif m["type"] == "health":
                    print("health:", m["status"], "camera", m["camera"], *m["events"], flush=True)
    except OSError as e:
        print("stream lost:", e, file=sys.stderr)
    sock.close()
