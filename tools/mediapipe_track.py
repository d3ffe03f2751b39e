#!/usr/bin/env python3
"""Run MediaPipe Face Mesh (478 landmarks) on a video or a webcam; write a dump or stream into `mimic serve`.

Setup (Python 3.11 on x86-64 Linux; the pins of tools/requirements-mediapipe.txt, installed with
--no-deps because mediapipe 0.10.21 would otherwise pull in jax, opencv-contrib and more that
Face Mesh does not use):

    python3 -m venv mpvenv
    mpvenv/bin/pip install --no-deps -r tools/requirements-mediapipe.txt

Run:

    # a video (or animated GIF, or still image) to a dump, then to a mimic recording:
    mpvenv/bin/python tools/mediapipe_track.py clip.mp4 -o clip.mediapipe.jsonl
    mimic import mediapipe clip.mediapipe.jsonl -o clip.jsonl
    # the webcam, live into `mimic serve --rig ict-face` (default address 127.0.0.1:7878):
    mpvenv/bin/python tools/mediapipe_track.py --camera 0 --to 127.0.0.1:7878 --session cam

Dump (-o): one JSON object per input frame, exactly what `mimic import mediapipe` reads
(docs/recording-format.md): {"frame": i, "t_us": t, "image_size": [w, h], "landmarks":
[[x, y, z], ... 478]}, or {"frame": i, "t_us": t, "landmarks": []} where no face was found. x, y, z
are MediaPipe's NormalizedLandmark values, 5 decimals. t_us: video files round(i * 1e6 / fps),
GIFs the frames' durations, still images 0, the webcam the time since the first frame.

Live (--to HOST:PORT): mimic's TCP JSON-lines tracker protocol (docs/protocol.md): a recording
header (layout mediapipe478, with --session and --rig), then one frame line per input frame, in
camera-space metres. The conversion is done here, in numpy, by the same method as
`mimic import mediapipe` (crates/mimic_capture/src/mediapipe.rs: a pinhole of vertical field of
view --fov-deg, the face given the canonical model's size by a weighted Procrustes scale over
MediaPipe's 33 Procrustes landmarks, each point unprojected at its own depth). Frames where no face
is found are sent as {"t_us": t, "points": [], "tracked": false}. A video file is sent at its own
pace (one frame per 1/fps), the webcam as fast as frames come.
"""
import argparse
import json
import os
import socket
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CANONICAL = os.path.join(REPO, "configs", "models", "mediapipe", "face_model_with_iris.obj")
IMAGE_EXT = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}
DEFAULT_FOV_DEG = 63.0  # MediaPipe's face-geometry default vertical field of view

# MediaPipe's 33 Procrustes landmarks and weights (geometry_pipeline_metadata_landmarks.pbtxt,
# v0.10.21), as mimic_capture::mediapipe::PROCRUSTES; positions come from the canonical OBJ.
PROCRUSTES = [
    (4, 0.070909939706326), (6, 0.032100144773722), (10, 0.008446550928056),
    (33, 0.058724168688059), (54, 0.007667080033571), (67, 0.009078059345484),
    (117, 0.009791937656701), (119, 0.014565368182957), (121, 0.018591361120343),
    (127, 0.005197994410992), (129, 0.120625205338001), (132, 0.005560018587857),
    (133, 0.05328618362546), (136, 0.066890455782413), (143, 0.014816547743976),
    (147, 0.014262833632529), (198, 0.025462191551924), (205, 0.047252278774977),
    (263, 0.058724168688059), (284, 0.007667080033571), (297, 0.009078059345484),
    (346, 0.009791937656701), (348, 0.014565368182957), (350, 0.018591361120343),
    (356, 0.005197994410992), (358, 0.120625205338001), (361, 0.005560018587857),
    (362, 0.05328618362546), (365, 0.066890455782413), (372, 0.014816547743976),
    (376, 0.014262833632529), (420, 0.025462191551924), (425, 0.047252278774977),
]


def frames_of(src, camera):
    """Yield (t_us, bgr_image) for every frame of a file, or of camera number `camera`."""
    import cv2
    if camera is not None:
        cap = cv2.VideoCapture(camera)
        if not cap.isOpened():
            sys.exit(f"cannot open camera {camera}")
        t0 = None
        while True:
            ok, img = cap.read()
            if not ok:
                break
            now = time.monotonic_ns() // 1000
            t0 = now if t0 is None else t0
            yield now - t0, img
        cap.release()
        return
    ext = os.path.splitext(src)[1].lower()
    if ext in IMAGE_EXT:
        img = cv2.imread(src, cv2.IMREAD_COLOR)
        if img is None:
            sys.exit(f"cannot read image {src}")
        yield 0, img
        return
    starts = None
    if ext == ".gif":
        from PIL import Image
        starts, t = [], 0
        with Image.open(src) as im:
            for k in range(getattr(im, "n_frames", 1)):
                im.seek(k)
                starts.append(t)
                t += int(im.info.get("duration", 0)) * 1000
    cap = cv2.VideoCapture(src)
    if not cap.isOpened():
        sys.exit(f"cannot open {src}")
    fps = cap.get(cv2.CAP_PROP_FPS) or 0.0
    i = 0
    while True:
        ok, img = cap.read()
        if not ok:
            break
        if starts is not None and i < len(starts):
            t_us = starts[i]
        elif fps > 0:
            t_us = round(i * 1e6 / fps)
        else:
            t_us = 0
        yield t_us, img
        i += 1
    cap.release()


def num(v):
    return f"{round(v, 5) + 0.0:.5f}"


class Metric:
    """Normalised landmarks -> camera-space metres, as mimic_capture::mediapipe::to_camera_space."""

    def __init__(self, fov_deg):
        import numpy as np
        self.np = np
        verts = [[float(t) for t in l.split()[1:4]] for l in open(CANONICAL) if l.startswith("v ")]
        self.ids = np.array([i for i, _ in PROCRUSTES])
        self.w = np.array([w for _, w in PROCRUSTES])
        c = np.array(verts)[self.ids]
        cc = (self.w[:, None] * c).sum(0) / self.w.sum()
        self.cs = (self.w * ((c - cc) ** 2).sum(1)).sum()
        self.tan = np.tan(np.radians(fov_deg) / 2)

    def __call__(self, landmarks, w, h):
        np = self.np
        p = np.asarray(landmarks, dtype=np.float64)
        f = h * 0.5 / self.tan
        s_px = np.stack([p[:, 0] * w - 0.5 * w, -(p[:, 1] * h - 0.5 * h), -p[:, 2] * w], 1)
        z0 = (self.w * s_px[self.ids, 2]).sum() / self.w.sum()
        depth = f - (s_px[:, 2] - z0)
        m = np.stack([s_px[:, 0] * depth / f, s_px[:, 1] * depth / f, -depth], 1)
        mp_ = m[self.ids]
        mc = (self.w[:, None] * mp_).sum(0) / self.w.sum()
        s = np.sqrt((self.w * ((mp_ - mc) ** 2).sum(1)).sum() / self.cs)
        if not np.isfinite(s) or s <= 1e-9:
            return None
        return m * (0.01 / s)


def connect(addr, session, rig, fov_deg):
    host, _, port = addr.rpartition(":")
    sock = socket.create_connection((host or "127.0.0.1", int(port)))
    header = {"format": "mimic-recording", "version": 1, "layout": "mediapipe478", "units": "m",
              "source": "MediaPipe Face Mesh 0.10.21, live (tools/mediapipe_track.py)",
              "rate_hz": 30.0, "point_count": 478,
              "description": f"live; pinhole with a {fov_deg} degree vertical field of view"}
    if session:
        header["session"] = session
    if rig:
        header["rig"] = rig
    sock.sendall((json.dumps(header) + "\n").encode())
    reply = sock.makefile("r")
    welcome = reply.readline().strip()
    print(f"mimic serve: {welcome}", file=sys.stderr)
    if '"error"' in welcome:
        sys.exit(1)
    return sock


def track(a):
    import cv2
    import mediapipe as mp
    out = open(a.output, "w") if a.output else None
    sock = connect(a.to, a.session, a.rig, a.fov_deg) if a.to else None
    metric = Metric(a.fov_deg) if sock else None
    n = hits = 0
    start = time.monotonic()
    with mp.solutions.face_mesh.FaceMesh(
            static_image_mode=False, max_num_faces=1, refine_landmarks=True,
            min_detection_confidence=0.5, min_tracking_confidence=0.5) as fm:
        for i, (t_us, bgr) in enumerate(frames_of(a.input, a.camera)):
            if a.max_frames is not None and i >= a.max_frames:
                break
            h, w = bgr.shape[:2]
            res = fm.process(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
            lms = res.multi_face_landmarks[0].landmark if res.multi_face_landmarks else None
            if out:
                if lms:
                    pts = ",".join(f"[{num(p.x)},{num(p.y)},{num(p.z)}]" for p in lms)
                    out.write(f'{{"frame":{i},"t_us":{t_us},"image_size":[{w},{h}],"landmarks":[{pts}]}}\n')
                else:
                    out.write(f'{{"frame":{i},"t_us":{t_us},"landmarks":[]}}\n')
            if sock:
                pts = metric([(p.x, p.y, p.z) for p in lms], w, h) if lms else None
                if pts is None:
                    line = {"t_us": t_us, "points": [], "tracked": False}
                else:
                    line = {"t_us": t_us, "points": [[float(f"{v:.6g}") for v in q] for q in pts]}
                if a.camera is None and a.pace:
                    # a video file: send at its own pace
                    wait = start + t_us * 1e-6 - time.monotonic()
                    if wait > 0:
                        time.sleep(wait)
                sock.sendall((json.dumps(line, separators=(",", ":")) + "\n").encode())
            hits += lms is not None
            n += 1
    if out:
        out.close()
    if sock:
        sock.shutdown(socket.SHUT_WR)
        for line in sock.makefile("r"):
            if '"bye"' in line:
                print(f"mimic serve: {line.strip()}", file=sys.stderr)
        sock.close()
    src = a.input if a.input else f"camera {a.camera}"
    print(f"{src}: {n} frames, {hits} with a face" + (f" -> {a.output}" if a.output else "")
          + (f" -> {a.to}" if a.to else ""), file=sys.stderr)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("input", nargs="?", help="video, animated GIF or still image")
    ap.add_argument("--camera", type=int, metavar="N", help="webcam number instead of a file")
    ap.add_argument("-o", "--output", metavar="DUMP.jsonl", help="write the MediaPipe dump here")
    ap.add_argument("--to", metavar="HOST:PORT", help="stream live into `mimic serve` at this TCP address")
    ap.add_argument("--session", help="session name for --to (viewers join by it)")
    ap.add_argument("--rig", help="rig for --to (default: the server's --rig)")
    ap.add_argument("--fov-deg", type=float, default=DEFAULT_FOV_DEG,
                    help="camera's vertical field of view for --to (default 63, MediaPipe's)")
    ap.add_argument("--no-pace", dest="pace", action="store_false",
                    help="with --to and a video file: send as fast as tracked, not at the video's pace")
    ap.add_argument("--max-frames", type=int, metavar="N", help="stop after N frames")
    a = ap.parse_args()
    if (a.input is None) == (a.camera is None):
        ap.error("give a VIDEO or --camera N (one of them)")
    if not a.output and not a.to:
        ap.error("give -o DUMP.jsonl, --to HOST:PORT, or both")
    if not 0 < a.fov_deg < 180:
        ap.error("--fov-deg must be in (0, 180)")
    track(a)
