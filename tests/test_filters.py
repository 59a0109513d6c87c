"""Temporal smoothing: the filters on known signals, gaps and short runs, per-track smoothing of
a real clip, and `--smooth` (the default) against `--no-smooth` in the CLI."""

import dataclasses
import json

import numpy as np
import pytest

from conftest import DATA, run_posecam, the_subject
from posecam.errors import InputError
from posecam.analysis.filters import SmoothOptions, butterworth, one_euro, runs, smooth_recording


def jitter(x: np.ndarray) -> float:
    """Mean norm of the second difference along frames (NaN-aware)."""
    return float(np.nanmean(np.linalg.norm(x[2:] - 2 * x[1:-1] + x[:-2], axis=-1)))


def test_butterworth_keeps_slow_motion_without_lag_and_removes_noise():
    fps, t = 60.0, np.arange(240) / 60.0
    slow = np.stack([300 * np.sin(2 * np.pi * 0.5 * t), 100 * np.cos(2 * np.pi * 1.0 * t), 4000 + 0 * t], axis=1)
    noisy = slow + np.random.default_rng(0).normal(0, 40, slow.shape)
    out = butterworth(noisy, fps, cutoff_hz=6.0)
    assert np.abs(butterworth(slow, fps)[10:-10] - slow[10:-10]).max() < 1.0      # zero phase: no lag
    assert np.abs(out - slow).mean() < 0.4 * np.abs(noisy - slow).mean()
    assert jitter(out) < 0.1 * jitter(noisy)


def test_gaps_split_runs_and_short_runs_stay_as_they_are():
    x = np.random.default_rng(1).normal(0, 10, (40, 2, 3))
    x[10:13] = np.nan                      # a gap
    x[13:16, 0] = np.nan                   # joint 0 comes back later than joint 1
    x[37] = np.nan                         # leaves a 2-frame run at the end
    out = butterworth(x, 30.0, 6.0)
    assert np.array_equal(np.isnan(out), np.isnan(x))
    np.testing.assert_array_equal(out[38:], x[38:])                 # too short to filter
    assert not np.allclose(out[:10], x[:10]) and not np.allclose(out[16:37], x[16:37])
    assert [(r.start, r.stop) for r in runs(np.isfinite(x[:, 0, 0]))] == [(0, 10), (16, 37), (38, 40)]


def test_one_euro_passes_constants_and_restarts_after_a_gap():
    x = np.full((20, 3), 7.0)
    x[8] = np.nan
    x[9:] = 50.0
    out = one_euro(x, 30.0)
    np.testing.assert_allclose(out[:8], 7.0)
    assert np.isnan(out[8]).all()
    np.testing.assert_allclose(out[9:], 50.0)                      # no memory of the old value


@pytest.mark.parametrize("kwargs", [{"method": "kalman"}, {"cutoff_hz": 0}, {"order": 3}, {"beta": -1}])
def test_bad_options_are_refused(kwargs):
    with pytest.raises(InputError):
        SmoothOptions(**kwargs)


@pytest.fixture(scope="module")
def clip(estimator):
    from posecam import PredictOptions

    return the_subject(estimator.predict_file(DATA / "balance_cam01_30f.mp4",   # the poses before smoothing
                                              options=PredictOptions(smooth=False, metric=None)))


def test_smoothing_follows_each_track_on_a_real_clip(clip):
    """A second, shifted person with another id: each track is smoothed on its own, so the
    first person's result does not change and the second is the first's plus the shift."""
    shift = np.array([900.0, 0.0, 300.0])
    frames = [dataclasses.replace(f, people=[*f.people, dataclasses.replace(f.people[0], id=99,
                                                                            keypoints_3d=f.people[0].keypoints_3d + shift)])
              for f in clip.frames]
    rec = dataclasses.replace(clip, frames=frames)
    alone, both = smooth_recording(clip), smooth_recording(rec)
    first = np.stack([f.people[0].keypoints_3d for f in alone.frames])
    np.testing.assert_allclose(np.stack([f.people[0].keypoints_3d for f in both.frames]), first)
    np.testing.assert_allclose(np.stack([f.people[1].keypoints_3d for f in both.frames]), first + shift, atol=1e-6)
    raw = np.stack([f.people[0].keypoints_3d for f in clip.frames])
    assert jitter(first) < 0.5 * jitter(raw)
    assert np.linalg.norm(first - raw, axis=-1).mean() < 60           # mm: smoothing, not moving
    assert clip.frames[3].people[0].keypoints_3d is not alone.frames[3].people[0].keypoints_3d   # a copy


def test_a_still_image_is_left_alone(estimator):
    from posecam.io.media import read_image

    frame = estimator.predict_image(read_image(DATA / "messi5.jpg"))
    from posecam.results import Recording

    rec = Recording("messi5.jpg", 1, 1, None, estimator.joints, [frame])
    np.testing.assert_array_equal(smooth_recording(rec).frames[0].people[0].keypoints_3d, frame.people[0].keypoints_3d)


def test_cli_smooths_videos_by_default(tmp_path):
    roots = {}
    for flag in ("--smooth", "--no-smooth"):
        out = tmp_path / f"{flag}.json"
        r = run_posecam("predict", DATA / "balance_cam01_30f.mp4", "-o", out, flag)
        assert r.returncode == 0, r.stderr
        doc = json.loads(out.read_text())
        roots[flag] = np.array([f["people"][0]["keypoints_3d"] for f in doc["inputs"][0]["frames"]])
    assert jitter(roots["--smooth"]) < 0.5 * jitter(roots["--no-smooth"])
    default = tmp_path / "default.json"
    assert run_posecam("predict", DATA / "balance_cam01_30f.mp4", "-o", default).returncode == 0
    kp = np.array([f["people"][0]["keypoints_3d"] for f in json.loads(default.read_text())["inputs"][0]["frames"]])
    np.testing.assert_allclose(kp, roots["--smooth"])


@pytest.mark.parametrize("order, cutoff, padlen", [(2, 0.2, 9), (1, 0.1, 3), (3, 0.45, 0), (2, 6 / 30, 12)])
def test_numpy_butterworth_is_scipys(order, cutoff, padlen):
    """posecam's own design and filtfilt give scipy.signal's numbers (scipy is the reference)."""
    from scipy.signal import butter, filtfilt

    from posecam.analysis.filters import _filtfilt, butter_lowpass

    b, a = butter(order, cutoff)
    ours_b, ours_a = butter_lowpass(order, cutoff)
    np.testing.assert_allclose(ours_b, b, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(ours_a, a, rtol=1e-12, atol=1e-15)
    x = np.cumsum(np.random.default_rng(order).normal(size=(150, 5)), axis=0)
    np.testing.assert_allclose(_filtfilt(b, a, x, padlen), filtfilt(b, a, x, axis=0, padlen=padlen),
                               rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("method", ["butterworth", "one_euro"])
def test_streaming_smoother_equals_smoothing_the_whole_video(method):
    """Frames pushed one by one through windows of bounded size come out as the whole video's
    smoothing: two people, one leaving for a while, over several blocks."""
    from posecam.analysis.filters import StreamingSmoother
    from posecam.geometry.camera import Intrinsics
    from posecam.results import Frame, Person, Recording

    rng = np.random.default_rng(3)
    n, j = 700, 17
    walk = np.cumsum(rng.normal(0, 5, size=(2, n, j, 3)), axis=1) + [0, 0, 3000]
    frames = []
    for i in range(n):
        people = [Person(pid, 0.9, np.zeros(4), walk[pid, i, :, :2] / 10, walk[pid, i], np.full(j, 0.9))
                  for pid in (0, 1) if not (pid == 1 and 250 <= i < 300)]
        frames.append(Frame(i, i / 60, people))
    rec = Recording("v.mp4", 640, 480, Intrinsics(500, 500, 320, 240), tuple(f"j{k}" for k in range(j)), frames, fps=60.0)
    options = SmoothOptions(method=method)
    whole = smooth_recording(rec, options).frames
    smoother = StreamingSmoother(dataclasses.replace(rec, frames=[]), options, block=150, margin=120)
    streamed, window = [], 0
    for frame in frames:
        streamed += smoother.push(frame)
        window = max(window, len(smoother._frames))
    streamed += smoother.flush()
    assert [f.index for f in streamed] == list(range(n))
    for a, b in zip(whole, streamed):
        assert [p.id for p in a.people] == [p.id for p in b.people]
        for p, q in zip(a.people, b.people):
            np.testing.assert_allclose(q.keypoints_3d, p.keypoints_3d, atol=1e-3)   # mm
    assert window <= 150 + 2 * 120          # memory: the window, not the video
