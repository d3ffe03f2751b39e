#!/usr/bin/env python3
"""Load run of mimic's cluster (docs/cluster.md, docs/performance.md): one nats-server, W
`mimic worker`s, one `mimic serve --nats` front door, S trackers (`mimic send --loop`), for T
seconds; prints frames/s retargeted and the front door's arrival -> broadcast latency (which
includes the NATS round trip to the worker and back). W = 0 runs the same load on a plain
`mimic serve` (no NATS), the baseline.

    tools/cluster_load.py --workers 2 --sessions 20 --secs 20 [--bin target/debug/mimic]
"""

import argparse
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def stats(addr):
    host, port = addr.rsplit(":", 1)
    with socket.create_connection((host, int(port)), timeout=10) as s:
        s.sendall(b'{"type":"stats"}\n')
        data = b""
        while not data.endswith(b"\n"):
            chunk = s.recv(1 << 20)
            if not chunk:
                break
            data += chunk
    return json.loads(data)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--sessions", type=int, default=10)
    ap.add_argument("--secs", type=float, default=20)
    ap.add_argument("--warmup", type=float, default=8)
    ap.add_argument("--bin", default="target/release/mimic")
    ap.add_argument("--rig", default="ict-face")
    ap.add_argument("--rec", default="recordings/a_affirmative.jsonl")
    ap.add_argument("--speed", type=float, default=4.0, help="x the recording's rate (GFE: 15 Hz)")
    a = ap.parse_args()
    nats_bin = os.environ.get("MIMIC_NATS_SERVER") or shutil.which("nats-server") or "/usr/sbin/nats-server"
    procs = []
    tmp = tempfile.mkdtemp()
    try:
        serve_args = [a.bin, "serve", "--listen", "127.0.0.1:0", "--no-udp", "--rig", a.rig,
                      "--max-sessions", str(a.sessions + 8)]
        if a.workers > 0:
            port = free_port()
            procs.append(subprocess.Popen([nats_bin, "-a", "127.0.0.1", "-p", str(port), "-js",
                                           "-sd", os.path.join(tmp, "js")],
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
            url = f"nats://127.0.0.1:{port}"
            deadline = time.time() + 20
            while True:
                try:
                    socket.create_connection(("127.0.0.1", port), timeout=1).close()
                    break
                except OSError:
                    if time.time() > deadline:
                        sys.exit("nats-server did not start")
                    time.sleep(0.05)
            for w in range(a.workers):
                p = subprocess.Popen([a.bin, "worker", "--nats", url, "--rig", a.rig,
                                      "--name", f"w{w + 1}", "--max-sessions",
                                      str(a.sessions)], stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, text=True)
                procs.append(p)
                p.stdout.readline()
            serve_args += ["--nats", url]
        serve = subprocess.Popen(serve_args, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                 text=True)
        procs.append(serve)
        addr = serve.stdout.readline().split()[3]
        for k in range(a.sessions):
            procs.append(subprocess.Popen([a.bin, "send", a.rec, "--to", addr, "--session",
                                           f"s{k}", "--loop", "--speed", str(a.speed)],
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        time.sleep(a.warmup)
        s0, t0 = stats(addr), time.time()
        time.sleep(a.secs)
        s1, t1 = stats(addr), time.time()
        frames = lambda s: sum(x["frames"] for x in s["sessions"])
        lost = lambda s: sum((x.get("cluster") or {}).get("lost", 0) for x in s["sessions"])
        held = {}
        for x in s1["sessions"]:
            w = (x.get("cluster") or {}).get("worker")
            held[w] = held.get(w, 0) + 1
        out = {
            "workers": a.workers,
            "sessions": a.sessions,
            "frames_per_s": round((frames(s1) - frames(s0)) / (t1 - t0)),
            "lost_in_window": lost(s1) - lost(s0),
            # The histogram covers the whole run (warm-up included).
            "p50_us": s1["latency"]["p50_us"],
            "p99_us": s1["latency"]["p99_us"],
            "max_us": s1["latency"]["max_us"],
            "sessions_per_worker": held,
        }
        print(json.dumps(out))
    finally:
        for p in reversed(procs):
            p.kill()
            p.wait()
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
