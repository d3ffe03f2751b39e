#!/usr/bin/env python3
"""Load run of mimic's cluster (docs/cluster.md; results in docs/performance.md, "Cluster over
NATS"). Per configuration: one nats-server on loopback, W `mimic worker`s, D `mimic serve --nats`
front doors, S tracker sessions at a fixed rate and a WebSocket viewer per session; W = 0 is the
baseline, one plain `mimic serve` (no NATS) under the same load, so the NATS hop's cost is the
difference in the same run.

The trackers (one Python process) send the recording's frames with `t_us` set to the wall clock
when the line is written, staggered evenly over the frame period; the viewers (another process)
read `/ws/SESSION` (docs/protocol.md: each binary frame carries `t_us` and the front door's
arrival time), so a viewer measures
  - tracker -> viewer: its receive time minus `t_us` (every path, also across front doors), and
  - arrival -> viewer: its receive time minus the front door's arrival stamp (same door only).
The front doors' `/stats` give frames accepted and the arrival -> broadcast histogram, the
cluster counters (`sent`, `retargeted`, `lost`) and viewer drops. CPU is read from /proc for
each role; the 1-minute load average and the machine's busy share are recorded per row.

    tools/cluster_load.py --workers 0,1,2,3 --sessions 8,16,32 --repeat 2 --secs 20 \\
        [--doors 1] [--rate 60] [--bin target/debug/mimic] [--json-out runs.jsonl] [--markdown]

With --doors 2 the trackers alternate between the two front doors and each session's viewer is
on the other one (the follow path: answers reach both doors over NATS). Configurations run
interleaved (every configuration once, then again), so the VM's speed states spread over them.
"""

import argparse
import base64
import json
import multiprocessing as mp
import os
import re
import selectors
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import time

CLK_TCK = os.sysconf("SC_CLK_TCK")


def now_us():
    return time.time_ns() // 1000


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def split_addr(addr):
    host, port = addr.rsplit(":", 1)
    return host, int(port)


def stats(addr):
    with socket.create_connection(split_addr(addr), timeout=10) as s:
        s.sendall(b'{"type":"stats"}\n')
        data = b""
        while not data.endswith(b"\n"):
            chunk = s.recv(1 << 20)
            if not chunk:
                break
            data += chunk
    return json.loads(data)


def cpu_s(pid):
    """User + system CPU seconds of a process (0 once it is gone)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / CLK_TCK
    except (OSError, IndexError, ValueError):
        return 0.0


def machine_cpu():
    """(busy, total) jiffies of the whole machine."""
    with open("/proc/stat") as f:
        v = [int(x) for x in f.readline().split()[1:]]
    idle = v[3] + v[4]
    return sum(v) - idle, sum(v)


def loadavg():
    with open("/proc/loadavg") as f:
        return float(f.read().split()[0])


def pct(sorted_values, q):
    if not sorted_values:
        return None
    i = min(len(sorted_values) - 1, max(0, int(round(q * (len(sorted_values) - 1)))))
    return sorted_values[i]


def read_recording(path):
    """The header (dict) and each frame line's text after its `t_us` value."""
    with open(path) as f:
        header = json.loads(f.readline())
        tails = []
        for n, line in enumerate(f, start=2):
            m = re.match(r'\{"t_us":-?\d+', line)
            if not m:
                sys.exit(f"{path}:{n}: a frame line must start with {{\"t_us\":")
            tails.append(line[m.end():].rstrip("\n"))
    if not tails:
        sys.exit(f"{path}: no frames")
    return header, tails


# ---------------------------------------------------------------------------------------------
# Trackers: one process, S TCP connections, frames staggered over the period.


def trackers(doors, sessions, header, tails, rate, stop, out):
    socks = []
    for k in range(sessions):
        h = dict(header, session=f"s{k}")
        s = socket.create_connection(split_addr(doors[k % len(doors)]), timeout=15)
        s.sendall((json.dumps(h) + "\n").encode())
        socks.append(s)
    # The welcome comes once the session has a worker (up to 5 s on a front door of a cluster).
    for k, s in enumerate(socks):
        buf = b""
        while b"\n" not in buf:
            chunk = s.recv(65536)
            if not chunk:
                out.put(("error", f"tracker s{k}: closed before its welcome"))
                return
            buf += chunk
        line = buf.split(b"\n", 1)[0]
        if b'"welcome"' not in line:
            out.put(("error", f"tracker s{k}: {line[:300]!r}"))
            return
        s.setblocking(False)
    out.put(("ready", None))
    period = 1.0 / rate
    step = period / sessions
    t0 = time.monotonic() + 0.05
    j = 0
    sent = [0] * sessions
    late = []
    pending = [b""] * sessions
    blocked = 0
    while not (j % sessions == 0 and stop.is_set()):
        due = t0 + j * step
        d = due - time.monotonic()
        if d > 0:
            time.sleep(d)
        else:
            late.append(-d)
        k = j % sessions
        i = j // sessions
        tail = tails[(i + 37 * k) % len(tails)]
        line = f'{{"t_us":{now_us()}{tail}\n'.encode()
        data = pending[k] + line
        try:
            n = socks[k].send(data)
        except BlockingIOError:
            n = 0
        if n < len(data):
            blocked += 1
        pending[k] = data[n:]
        sent[k] += 1
        j += 1
        if j % (4 * sessions) == 0:
            for s in socks:  # replies (errors, none expected) are read and dropped
                try:
                    while s.recv(65536):
                        pass
                except (BlockingIOError, ConnectionError):
                    pass
    late.sort()
    out.put(("done", {"sent": sum(sent), "blocked_writes": blocked,
                      "late_p99_ms": round(1e3 * (pct(late, 0.99) or 0.0), 2),
                      "late_share": round(len(late) / max(1, j), 3)}))
    # Keep the connections until the parent ends this process (the sessions stay live).
    time.sleep(3600)


# ---------------------------------------------------------------------------------------------
# Viewers: one process, a WebSocket per viewed session.


def ws_connect(addr, path):
    s = socket.create_connection(split_addr(addr), timeout=15)
    key = base64.b64encode(os.urandom(16)).decode()
    s.sendall((f"GET {path} HTTP/1.1\r\nHost: {addr}\r\nUpgrade: websocket\r\n"
               f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
               "Sec-WebSocket-Version: 13\r\n\r\n").encode())
    buf = b""
    while b"\r\n\r\n" not in buf:
        chunk = s.recv(65536)
        if not chunk:
            raise ConnectionError(f"{addr}{path}: closed during the handshake")
        buf += chunk
    head, rest = buf.split(b"\r\n\r\n", 1)
    if b" 101 " not in head.split(b"\r\n", 1)[0]:
        raise ConnectionError(f"{addr}{path}: {head[:200]!r}")
    return s, rest


def ws_messages(buf):
    """Complete server messages (opcode, payload) at the front of buf, and the rest."""
    msgs = []
    while len(buf) >= 2:
        op, ln = buf[0] & 0x0F, buf[1] & 0x7F
        at = 2
        if ln == 126:
            if len(buf) < 4:
                break
            ln, at = struct.unpack_from(">H", buf, 2)[0], 4
        elif ln == 127:
            if len(buf) < 10:
                break
            ln, at = struct.unpack_from(">Q", buf, 2)[0], 10
        if len(buf) < at + ln:
            break
        msgs.append((op, buf[at:at + ln]))
        buf = buf[at + ln:]
    return msgs, buf


def viewers(http, sessions, doors_n, stop, out):
    """Viewer of session k on door (k + 1) % doors_n: the other door when there are two."""
    sel = selectors.DefaultSelector()
    state = {}
    for k in range(sessions):
        door = (k + 1) % doors_n
        s, rest = ws_connect(http[door], f"/ws/s{k}")
        s.setblocking(False)
        st = {"k": k, "buf": rest, "last": None, "frames": 0,
              "same_door": doors_n == 1}
        state[s.fileno()] = st
        sel.register(s, selectors.EVENT_READ, st)
    out.put(("ready", None))
    # (receive time, tracker -> viewer, arrival -> viewer or -1, sequence numbers skipped),
    # flattened.
    samples = []
    while not stop.is_set():
        for key, _ in sel.select(timeout=0.2):
            st = key.data
            try:
                chunk = key.fileobj.recv(1 << 20)
            except BlockingIOError:
                continue
            t = now_us()
            if not chunk:
                sel.unregister(key.fileobj)
                continue
            msgs, st["buf"] = ws_messages(st["buf"] + chunk)
            for op, p in msgs:
                if op != 2 or len(p) < 32:
                    continue
                seq, t_us, arrival, _sent = struct.unpack_from("<Qqqq", p, 0)
                gap = 0
                if st["last"] is not None and seq > st["last"] + 1:
                    gap = seq - st["last"] - 1
                st["last"] = seq
                st["frames"] += 1
                samples.extend((t, t - t_us, t - arrival if st["same_door"] else -1, gap))
    out.put(("done", {"samples": samples}))
    time.sleep(3600)


# ---------------------------------------------------------------------------------------------
# One configuration.


class Run:
    def __init__(self):
        self.procs = []  # (role, Popen or Process)
        self.tmp = tempfile.mkdtemp(prefix="mimic-cluster-load-")

    def popen(self, role, args):
        p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        self.procs.append((role, p))
        return p

    def close(self):
        for _, p in reversed(self.procs):
            if isinstance(p, subprocess.Popen):
                p.kill()
                p.wait()
            else:
                p.kill()
                p.join()
        shutil.rmtree(self.tmp, ignore_errors=True)

    def cpu(self):
        by_role = {}
        for role, p in self.procs:
            by_role[role] = by_role.get(role, 0.0) + cpu_s(p.pid)
        return by_role


def first_line(p, what):
    line = p.stdout.readline()
    if not line:
        sys.exit(f"{what} exited before its ready line (exit {p.wait()})")
    return line


def run_config(a, workers, doors, sessions, nats_bin, header, tails):
    r = Run()
    try:
        serve_args = [a.bin, "serve", "--listen", "127.0.0.1:0", "--no-udp", "--rig", a.rig,
                      "--max-sessions", str(sessions + 8), "--http", "127.0.0.1:0"]
        if workers > 0:
            port = free_port()
            r.popen("nats", [nats_bin, "-a", "127.0.0.1", "-p", str(port), "-js",
                             "-sd", os.path.join(r.tmp, "js")])
            deadline = time.time() + 20
            while True:
                try:
                    socket.create_connection(("127.0.0.1", port), timeout=1).close()
                    break
                except OSError:
                    if time.time() > deadline:
                        sys.exit("nats-server did not start")
                    time.sleep(0.05)
            url = f"nats://127.0.0.1:{port}"
            ws = [r.popen("worker", [a.bin, "worker", "--nats", url, "--rig", a.rig,
                                     "--name", f"w{w + 1}", "--max-sessions", str(sessions)])
                  for w in range(workers)]
            for w, p in enumerate(ws):
                first_line(p, f"worker w{w + 1}")
            serve_args += ["--nats", url]
        tcp, http = [], []
        fronts = [r.popen("front", serve_args) for _ in range(doors if workers > 0 else 1)]
        for p in fronts:
            line = first_line(p, "mimic serve")
            tcp.append(re.search(r"tcp (\S+)", line).group(1))
            http.append(re.search(r"http (\S+)", line).group(1))
        q_v, q_t, stop = mp.Queue(), mp.Queue(), mp.Event()
        v = mp.Process(target=viewers, args=(http, sessions, len(http), stop, q_v), daemon=True)
        v.start()
        r.procs.append(("harness", v))
        if q_v.get(timeout=60)[0] != "ready":
            sys.exit("viewers did not connect")
        t = mp.Process(target=trackers, args=(tcp, sessions, header, tails, a.rate, stop, q_t),
                       daemon=True)
        t.start()
        r.procs.append(("harness", t))
        msg = q_t.get(timeout=60)
        if msg[0] != "ready":
            sys.exit(f"trackers: {msg[1]}")
        time.sleep(a.warmup)
        load = loadavg()
        s0 = [stats(x) for x in tcp]
        c0, m0, w0 = r.cpu(), machine_cpu(), now_us()
        time.sleep(a.secs)
        s1 = [stats(x) for x in tcp]
        c1, m1, w1 = r.cpu(), machine_cpu(), now_us()
        load_end = loadavg()
        stop.set()
        v_res, t_res = q_v.get(timeout=60), q_t.get(timeout=60)
        if v_res[0] != "done" or t_res[0] != "done":
            sys.exit(f"harness: {v_res[1] if v_res[0] != 'done' else t_res[1]}")
        return summarize(workers, len(http), sessions, a.rate, s0, s1, (c0, c1), (m0, m1),
                         (w0, w1), (load, load_end), v_res[1], t_res[1])
    finally:
        r.close()


def session_rows(s):
    """The front door's hosted sessions with frames (followers of other doors' have none)."""
    return [x for x in s["sessions"] if x.get("active") and x.get("frames", 0) > 0]


def summarize(workers, doors, sessions, rate, s0, s1, cpu, mach, window, load, view, track):
    """One row: rates over the window, latencies, losses, CPU."""
    (c0, c1), (m0, m1), (w0, w1) = cpu, mach, window
    dt = (w1 - w0) / 1e6

    def total(snaps, f):
        return sum(f(x) for s in snaps for x in session_rows(s))

    def delta(f):
        return total(s1, f) - total(s0, f)

    def cl(x, key, default):
        return (x.get("cluster") or {}).get(key, default)

    held = {}
    for s in s1:
        for x in session_rows(s):
            w = cl(x, "worker", None) or "front"
            held[w] = held.get(w, 0) + 1
    sm = view["samples"]
    win = [i for i in range(0, len(sm), 4) if w0 <= sm[i] < w1]
    e2e = sorted(sm[i + 1] for i in win)
    arr = sorted(sm[i + 2] for i in win if sm[i + 2] >= 0)
    us = lambda v: None if v is None else int(v)
    dropped = sum(s.get("viewer_frames_dropped", 0) for s in s1) - \
        sum(s.get("viewer_frames_dropped", 0) for s in s0)
    return {
        "workers": workers, "doors": doors, "sessions": sessions, "rate": rate,
        "load1": load[0], "load1_end": load[1], "secs": round(dt, 2),
        "accepted_per_s": round(delta(lambda x: x["frames"]) / dt, 1),
        "retargeted_per_s": round(delta(lambda x: cl(x, "retargeted", x["frames"])) / dt, 1),
        "viewer_per_s": round(len(e2e) / dt, 1),
        "lost": delta(lambda x: cl(x, "lost", 0)),
        # Placements past each session's first: failovers (a worker's lease expired).
        "failovers": total(s1, lambda x: max(0, cl(x, "placements", 1) - 1)),
        "viewer_dropped": dropped,
        "viewer_seq_gaps": sum(sm[i + 3] for i in win),
        "e2e_p50_us": us(pct(e2e, 0.5)), "e2e_p99_us": us(pct(e2e, 0.99)),
        "arrival_viewer_p50_us": us(pct(arr, 0.5)), "arrival_viewer_p99_us": us(pct(arr, 0.99)),
        # The front doors' arrival -> broadcast histograms cover the whole run (warm-up too).
        "server_p50_us": max(s["latency"]["p50_us"] for s in s1),
        "server_p99_us": max(s["latency"]["p99_us"] for s in s1),
        "held": held,
        "cpu_pct": {k: round(100 * (c1.get(k, 0) - c0.get(k, 0)) / dt, 1) for k in c1},
        "machine_busy_pct": round(100 * (m1[0] - m0[0]) / max(1, m1[1] - m0[1]), 1),
        "tracker": track,
    }


def ms(v):
    return "-" if v is None else f"{v / 1000:.2f}"


def print_table(rows):
    print("| W | doors | S | load | accepted/s | to viewers/s | tracker->viewer p50 / p99 ms "
          "| arrival->viewer p50 / p99 ms | arrival->broadcast p50 / p99 ms | lost / seq gaps / dropped | "
          "CPU % front / workers / nats | busy % |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        c = r["cpu_pct"]
        print(f"| {r['workers'] or 'none'} | {r['doors']} | {r['sessions']} | {r['load1']:.1f} "
              f"| {r['accepted_per_s']:.0f} | {r['viewer_per_s']:.0f} "
              f"| {ms(r['e2e_p50_us'])} / {ms(r['e2e_p99_us'])} "
              f"| {ms(r['arrival_viewer_p50_us'])} / {ms(r['arrival_viewer_p99_us'])} "
              f"| {ms(r['server_p50_us'])} / {ms(r['server_p99_us'])} "
              f"| {r['lost']} / {r['viewer_seq_gaps']} / {r['viewer_dropped']} "
              f"| {c.get('front', 0):.0f} / {c.get('worker', 0):.0f} / {c.get('nats', 0):.0f} "
              f"| {r['machine_busy_pct']:.0f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", default="0,1,2,3", help="comma list; 0 = plain mimic serve")
    ap.add_argument("--sessions", default="8,16,32", help="comma list")
    ap.add_argument("--doors", type=int, default=1, choices=[1, 2])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--secs", type=float, default=20)
    ap.add_argument("--warmup", type=float, default=5)
    ap.add_argument("--rate", type=float, default=60, help="frames/s per session")
    ap.add_argument("--bin", default="target/debug/mimic")
    ap.add_argument("--rig", default="ict-face")
    ap.add_argument("--rec", default="recordings/a_affirmative.jsonl")
    ap.add_argument("--nats-server", default=os.environ.get("MIMIC_NATS_SERVER")
                    or shutil.which("nats-server") or "/usr/sbin/nats-server")
    ap.add_argument("--json-out", help="append one JSON line per run here")
    ap.add_argument("--markdown", action="store_true", help="print the rows as a table too")
    a = ap.parse_args()
    header, tails = read_recording(a.rec)
    ws = [int(x) for x in a.workers.split(",")]
    ss = [int(x) for x in a.sessions.split(",")]
    if any(w > 0 for w in ws) and not os.access(a.nats_server, os.X_OK):
        sys.exit(f"no nats-server at {a.nats_server} (--nats-server or MIMIC_NATS_SERVER)")
    rows = []
    for rep in range(a.repeat):
        for s in ss:
            for w in ws:
                row = run_config(a, w, a.doors, s, a.nats_server, header, tails)
                row["repeat"] = rep + 1
                rows.append(row)
                print(json.dumps(row), flush=True)
                if a.json_out:
                    with open(a.json_out, "a") as f:
                        f.write(json.dumps(row) + "\n")
    if a.markdown:
        print_table(rows)


if __name__ == "__main__":
    main()
