"""Live sources: a camera index and stream URLs, tried on an MJPEG stream served over HTTP on
the loopback address by this test (the frames of a real clip), bounded in time."""

from __future__ import annotations

import http.server
import json
import signal
import socketserver
import subprocess
import sys
import threading
import time

import cv2
import pytest

from conftest import DATA, run_posecam

CLIP = DATA / "balance_cam01_30f.mp4"


def _jpegs() -> list[bytes]:
    cap, frames = cv2.VideoCapture(str(CLIP)), []
    while True:
        ok, bgr = cap.read()
        if not ok:
            return frames
        frames.append(cv2.imencode(".jpg", bgr)[1].tobytes())


@pytest.fixture
def mjpeg():
    """serve(loops) -> URL of a multipart MJPEG stream of the clip at 30 fps: `loops` times
    through its 30 frames then closed, or without end (None)."""
    frames, servers = _jpegs(), []

    def serve(loops: int | None) -> str:
        class Stream(http.server.BaseHTTPRequestHandler):
            def do_GET(self):
                self.send_response(200)
                self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
                self.end_headers()
                i = 0
                try:
                    while loops is None or i < loops * len(frames):
                        jpg = frames[i % len(frames)]
                        self.wfile.write(b"--frame\r\nContent-Type: image/jpeg\r\nContent-Length: %d\r\n\r\n"
                                         % len(jpg) + jpg + b"\r\n")
                        i += 1
                        time.sleep(1 / 30)
                except (BrokenPipeError, ConnectionResetError):
                    pass

            def log_message(self, *args):
                pass

        server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), Stream)
        server.daemon_threads = True
        threading.Thread(target=server.serve_forever, daemon=True).start()
        servers.append(server)
        return f"http://127.0.0.1:{server.server_address[1]}/live.mjpg"

    yield serve
    for server in servers:
        server.shutdown()
        server.server_close()


def _staged_bytes(folder) -> int:
    """Bytes of the pose file posecam is writing (staged in a .posecam-<pid>- folder until done)."""
    return sum(p.stat().st_size for p in folder.glob(".posecam-*/*.json"))


def test_a_stream_that_ends_is_read_to_its_end(mjpeg, tmp_path):
    url, out = mjpeg(1), tmp_path / "live.json"
    run = run_posecam("predict", url, "-o", out, "--angles")
    assert run.returncode == 0, run.stderr
    rec = json.loads(out.read_text())["inputs"][0]
    assert rec["source"] == url and rec["width"] == 540 and rec["height"] == 960
    frames = rec["frames"]
    # the first frame the opening check read is lost to the stream; OpenCV may drop one more
    assert len(frames) >= 28 and [f["index"] for f in frames] == list(range(len(frames)))
    assert all(f["people"] and "angles" in f["people"][0] for f in frames[5:])


@pytest.mark.slow
def test_ctrl_c_ends_a_live_stream_with_complete_files(mjpeg, tmp_path):
    url, out, video = mjpeg(None), tmp_path / "live.json", tmp_path / "live.mp4"
    proc = subprocess.Popen([sys.executable, "-m", "posecam", "predict", url, "-o", str(out), "--viz", str(video)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and _staged_bytes(tmp_path) < 20_000:   # frames being written
            time.sleep(0.2)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 0, stderr
    assert "stopping after this frame" in stderr and "Traceback" not in stderr
    frames = json.loads(out.read_text())["inputs"][0]["frames"]    # a complete JSON document
    assert len(frames) >= 10 and [f["index"] for f in frames] == list(range(len(frames)))
    cap = cv2.VideoCapture(str(video))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == len(frames)
    assert f"wrote {out}" in stdout.replace("\n", "")


@pytest.mark.slow
def test_a_second_ctrl_c_abandons_the_outputs(mjpeg, tmp_path):
    """The second Ctrl-C lands while posecam finishes (drawing the 3D view of every frame, which
    takes seconds): nothing is written, exit 130."""
    url, out = mjpeg(None), tmp_path / "live.json"
    proc = subprocess.Popen([sys.executable, "-m", "posecam", "predict", url, "-o", str(out),
                             "--viz3d", str(tmp_path / "view.mp4")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and _staged_bytes(tmp_path) < 100_000:
            time.sleep(0.2)
        proc.send_signal(signal.SIGINT)
        time.sleep(0.3)
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130 and "posecam: interrupted" in stderr and "Traceback" not in stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args, message", [
    (["7"], "camera 7 cannot be opened"),
    (["http://127.0.0.1:9/none.mjpg"], "stream http://127.0.0.1:9/none.mjpg cannot be opened"),
    (["0", str(CLIP)], "a camera or a stream is predicted alone"),
    ([str(CLIP), "--show"], "--show needs a display"),
])
def test_live_sources_refused_clearly(args, message, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    run = run_posecam("predict", *args)
    assert run.returncode == 2 and message in run.stderr and "Traceback" not in run.stderr
