"""--start/--end/--stride: part of a video or sequence, read by seeking and grabbing, with the
source's frame indices and times in every output."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from posecam.errors import InputError
from posecam.io.media import FrameSelection, open_media

from conftest import DATA, run_posecam

CLIP = DATA / "balance_cam01_30f.mp4"   # 30 frames at 60 fps


@pytest.mark.parametrize("start, end, stride, fps, count, expected", [
    (None, None, None, 60.0, 30, range(0, 30)),
    ("5", None, None, 60.0, 30, range(5, 30)),
    ("0.25s", "0.4s", None, 60.0, 30, range(15, 24)),
    ("2", "20", "3", 60.0, 30, range(2, 20, 3)),
    (None, "100", "0.05s", 60.0, 30, range(0, 30, 3)),      # an end past the input stops at its end
    (".5s", None, None, 30.0, 30, range(15, 30)),
])
def test_selection_in_frames_or_seconds(start, end, stride, fps, count, expected):
    assert FrameSelection(start, end, stride).frames(fps, count) == expected


@pytest.mark.parametrize("start, end, stride, message", [
    ("-1", None, None, "--start takes a frame number"),
    ("1.5", None, None, "--start takes a frame number"),    # frames are whole; seconds end in s
    (None, "2 s", None, "--end takes a frame number"),
    (None, None, "0", "--stride must be at least one frame"),
    ("10", "10", None, "is not before --end 10"),
    ("40", None, None, "is not before the end of the input (30 frames at 60 fps)"),
])
def test_bad_selections_are_refused(start, end, stride, message):
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        FrameSelection(start, end, stride).frames(60.0, 30)


def _all_frames(path) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, bgr = cap.read()
        if not ok:
            return frames
        frames.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))


def test_seeked_and_strided_frames_are_the_source_frames():
    every = _all_frames(CLIP)
    media = open_media(CLIP, FrameSelection("7", "26", "4"))
    got = list(media.frames())
    assert [i for i, _, _ in got] == [7, 11, 15, 19, 23] == list(media.selected)
    assert [t for _, t, _ in got] == pytest.approx([i / 60 for i in (7, 11, 15, 19, 23)])
    for i, _, rgb in got:
        assert np.array_equal(rgb, every[i]), i
    assert media.sample_fps == pytest.approx(15.0)


def test_a_sequence_is_sliced_too(tmp_path):
    every = _all_frames(CLIP)[:12]
    for i, rgb in enumerate(every):
        cv2.imwrite(str(tmp_path / f"frame_{i:03d}.png"), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    media = open_media(tmp_path, FrameSelection("0.1s", None, "5"))    # 30 fps sequence: frame 3
    got = list(media.frames())
    assert [i for i, _, _ in got] == [3, 8] and np.array_equal(got[1][2], every[8])


def test_predict_keeps_source_indices_and_times(tmp_path):
    out, trc = tmp_path / "part.json", tmp_path / "part.trc"
    run = run_posecam("predict", CLIP, "--start", "0.1s", "--end", "24", "--stride", "2", "-o", out)
    assert run.returncode == 0, run.stderr
    rec = json.loads(out.read_text())["inputs"][0]
    assert [f["index"] for f in rec["frames"]] == list(range(6, 24, 2))
    assert [f["time"] for f in rec["frames"]] == pytest.approx([i / 60 for i in range(6, 24, 2)], abs=1e-4)
    assert rec["fps"] == pytest.approx(30.0) and all(f["people"] for f in rec["frames"])
    run = run_posecam("predict", CLIP, "--start", "20", "-o", trc, "--max-people", "1")   # the adult, not the bystander: one .trc
    assert run.returncode == 0, run.stderr
    rows = [line.split("\t") for line in trc.read_text().splitlines()[5:] if line.strip()]
    assert rows[0][:2] == ["21", "0.333333"] and len(rows) == 10    # TRC counts frames from 1


@pytest.mark.parametrize("args, message", [
    ([DATA / "messi5.jpg", "--start", "1"], "is an image"),
    ([CLIP, "--start", "31"], "is not before the end of the input"),
    ([CLIP, "--stride", "fast"], "--stride takes a frame number"),
])
def test_predict_refuses_bad_selections(tmp_path, args, message):
    run = run_posecam("predict", *args, "-o", tmp_path / "x.json")
    assert run.returncode == 2 and message in run.stderr and "Traceback" not in run.stderr
    assert not (tmp_path / "x.json").exists()


def test_fuse_picks_the_same_frames_of_pose_files(tmp_path):
    from synth_rig import write_take

    _, paths, _ = write_take(tmp_path, 60)
    out = tmp_path / "fused.json"
    run = run_posecam("fuse", *paths, "--calibration", tmp_path / "calib.toml", "--start", "10", "--end", "50",
                      "--stride", "2", "-o", out)
    assert run.returncode == 0, run.stderr
    frames = json.loads(out.read_text())["inputs"][0]["frames"]
    assert [f["index"] for f in frames] == list(range(10, 50, 2)) and all(f["people"] for f in frames)
    run = run_posecam("fuse", *paths, "--stride", "2", "--sync", "auto", "-o", out)
    assert run.returncode == 2 and "--stride does not go with --sync auto" in run.stderr
