#!/usr/bin/env python3
"""Floods a `mimic serve --record` child on loopback and reports its peak RSS (VmHWM).

The flood (docs/reliability.md, "Memory under a flood"): the server's maximum of tracker sessions,
each sending a recording re-timed in a loop as fast as TCP takes it, with a line over the 1 MiB
message limit after every 500 frames and never reading its replies; the maximum of viewers, half
of them asking for positions, none ever reading (kept connected: `--viewer-write-timeout 3600`); trackers and viewers beyond the limits; 8 connections holding half a hello (half the 16
connection slots beyond sessions + viewers); garbage UDP packets. Then Ctrl-C (SIGINT) while the trackers are
still sending. Checks afterwards: the server exited 0, and every session's recording holds exactly
the frames the server accepted (`frames == recorded`, `record_lost == 0`, and the file's line count).

Run from the repository root (standard library only):
    python3 tools/flood_serve.py [--mimic target/debug/mimic] [--rig ict-face] [--seconds 60]
"""

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time


def status_kb(pid, field):
    """A `/proc/PID/status` field in kB (None once the process is gone)."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def stats(addr):
    s = socket.create_connection(addr, timeout=60)
    s.sendall(b'{"type":"stats"}\n')
    data = b""
    while True:
        chunk = s.recv(1 << 20)
        if not chunk:
            break
        data += chunk
    s.close()
    return json.loads(data)


def tracker(addr, name, header, rests, stop, sent, oversize_every):
    """Sends frames re-timed in a loop as fast as the socket takes them; never reads after welcome."""
    try:
        s = socket.create_connection(addr, timeout=600)
        h = dict(header)
        h["session"] = name
        s.sendall((json.dumps(h) + "\n").encode())
        welcome = s.makefile("rb").readline()
        if b'"welcome"' not in welcome:
            sent[name] = ("refused", welcome.decode(errors="replace").strip())
            return
        oversize = b"x" * ((1 << 20) + 4096) + b"\n"
        t, frames, big = 0, 0, 0
        while not stop.is_set():
            chunk = []
            for rest in rests:
                t += 33_334
                chunk.append('{"t_us":%d,%s' % (t, rest))
            s.sendall("".join(chunk).encode())
            frames += len(rests)
            if frames % oversize_every < len(rests):
                s.sendall(oversize)
                big += 1
        sent[name] = ("ok", frames, big)
        s.close()
    except OSError as e:
        # Expected once the server shuts down mid-send.
        sent[name] = ("closed", str(e))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mimic", default="target/debug/mimic")
    ap.add_argument("--rig", default="ict-face")
    ap.add_argument("--recording", default="recordings/openface_test.jsonl")
    ap.add_argument("--sessions", type=int, default=128, help="= --max-sessions")
    ap.add_argument("--viewers", type=int, default=256, help="= --max-viewers")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--record", default=None, help="recording folder (default: a temporary one)")
    ap.add_argument("--configs", default=None, help="config folder for mimic serve (default: ./configs)")
    args = ap.parse_args()

    lines = open(args.recording).read().splitlines()
    header = json.loads(lines[0])
    rests = [l.split(",", 1)[1] + "\n" for l in lines[1:] if l.strip()]
    tmp = None
    record = args.record
    if record is None:
        tmp = tempfile.TemporaryDirectory(prefix="mimic-flood-")
        record = tmp.name
    cmd = [args.mimic, "serve", "--rig", args.rig, "--listen", "127.0.0.1:0", "--record", record,
           "--max-sessions", str(args.sessions), "--max-viewers", str(args.viewers), "--json",
           # Stalled viewers stay connected (and their queues full) for the whole flood.
           "--viewer-write-timeout", "3600"]
    if args.configs:
        cmd += ["--configs", args.configs]
    print("$", " ".join(cmd), flush=True)
    serve = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    first = serve.stdout.readline().split()
    host, port = first[3].rsplit(":", 1)
    addr, udp_addr = (host, int(port)), first[5].rsplit(":", 1)
    pid = serve.pid
    # The final counters (--json) are read as they come, so the server never blocks on stdout.
    rest = []
    reader = threading.Thread(target=lambda: rest.append(serve.stdout.read()), daemon=True)
    reader.start()
    idle_kb = status_kb(pid, "VmRSS")
    print(f"started: tcp {first[3]}; RSS idle (rig loaded) {idle_kb / 1024:.0f} MiB", flush=True)

    stop = threading.Event()
    sent = {}
    threads = []
    held = []
    # Viewers first (they wait for their session), none ever reads; half want positions.
    for i in range(args.viewers + 8):
        v = socket.create_connection(addr)
        hello = {"type": "viewer", "session": f"flood{i % args.sessions}", "positions": i % 2 == 0}
        v.sendall((json.dumps(hello) + "\n").encode())
        held.append(v)
    for i in range(args.sessions + 8):
        th = threading.Thread(target=tracker, daemon=True,
                              args=(addr, f"flood{i}", header, rests, stop, sent, 500))
        th.start()
        threads.append(th)
    # Half a hello, never finished (closed by the server after its idle timeout). Eight of the 16
    # connections beyond sessions + viewers: the other eight stay free for stats requests.
    for _ in range(8):
        c = socket.create_connection(addr)
        c.sendall(b'{"type":"viewer","session":"' + b"y" * 60_000)
        held.append(c)
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def udp_garbage():
        junk = os.urandom(1228)
        while not stop.is_set():
            try:
                udp.sendto(junk, (udp_addr[0], int(udp_addr[1])))
            except OSError:
                pass
            time.sleep(0.0005)

    threading.Thread(target=udp_garbage, daemon=True).start()

    start = time.time()
    peak_kb, rss_kb = 0, 0
    next_report = start + 10
    while time.time() - start < args.seconds:
        hwm = status_kb(pid, "VmHWM")
        rss_kb = status_kb(pid, "VmRSS") or rss_kb
        peak_kb = max(peak_kb, hwm or 0)
        if time.time() >= next_report:
            s = stats(addr)
            frames = sum(x["frames"] for x in s["sessions"])
            print(f"t={time.time() - start:5.1f}s RSS {rss_kb / 1024:6.0f} MiB  VmHWM {peak_kb / 1024:6.0f} MiB  "
                  f"sessions {s['sessions_active']} viewers {s['viewers_active']} frames {frames} "
                  f"viewer drops {s['viewer_frames_dropped']}", flush=True)
            next_report += 10
        time.sleep(0.25)

    # Ctrl-C while the trackers are still sending.
    t0 = time.time()
    serve.send_signal(signal.SIGINT)
    while serve.poll() is None:
        peak_kb = max(peak_kb, status_kb(pid, "VmHWM") or 0)
        time.sleep(0.05)
        if time.time() - t0 > 300:
            serve.kill()
            sys.exit("mimic serve did not stop within 300 s of SIGINT")
    shutdown_s = time.time() - t0
    stop.set()
    reader.join()
    final = json.loads(rest[0])
    assert serve.returncode == 0, serve.returncode

    sessions = final["sessions"]
    frames = sum(s["frames"] for s in sessions)
    recorded = sum(s["recorded"] for s in sessions)
    lost = sum(s["record_lost"] for s in sessions)
    waits = sum(s["record_waits"] for s in sessions)
    malformed = sum(s["malformed"] for s in sessions)
    bad = []
    file_frames = 0
    for s in sessions:
        if s["frames"] != s["recorded"] or s["record_lost"] != 0:
            bad.append((s["name"], s["frames"], s["recorded"], s["record_lost"]))
        n = -1  # the header line
        with open(s["recording"], "rb") as f:
            data = f.read()
            assert data.endswith(b"\n"), s["recording"]
            n += data.count(b"\n")
        file_frames += n
        if n != s["recorded"]:
            bad.append((s["name"], "file has", n, "recorded", s["recorded"]))
    refused_trackers = sum(1 for v in sent.values() if v[0] == "refused")
    print(f"flood: {args.seconds:.0f} s, {len(sessions)} sessions (+{refused_trackers} refused), "
          f"{args.viewers} stalled viewers (+8 refused), 8 half hellos, UDP garbage")
    print(f"peak RSS (VmHWM): {peak_kb / 1024:.0f} MiB; idle {idle_kb / 1024:.0f} MiB; "
          f"shutdown took {shutdown_s:.1f} s")
    print(f"server: connections {final['connections']}, refused {final['refused']}, "
          f"frames accepted {frames}, malformed {malformed}, "
          f"viewer frames dropped {final['viewer_frames_dropped']}, udp bad {final['udp_bad_packets']}, "
          f"replies dropped {sum(s['replies_dropped'] for s in sessions)}")
    print(f"recordings: {recorded} frames recorded, {file_frames} in the files, {lost} lost, "
          f"{waits} waits for the disk")
    if bad:
        sys.exit(f"accepted frames missing from recordings: {bad[:5]}")
    print("every accepted frame is in its session's recording")
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
