"""Temporal smoothing of pose trajectories, one track at a time.

    from posecam.analysis.filters import SmoothOptions, smooth_recording
    smoothed = smooth_recording(rec, SmoothOptions(cutoff_hz=6.0))

Two standard filters over (F, ...) arrays whose missing frames are NaN:
- `butterworth`: zero-phase low-pass (forward and backward, as Pose2Sim filters its
  trajectories with scipy's `butter` + `filtfilt`; written here in numpy with the same
  design, padding and initial conditions, because importing scipy.signal costs a third of a
  second per run); each unbroken run of frames is filtered on its own.
- `one_euro`: the One-Euro filter (Casiez et al., CHI 2012), causal and speed-adaptive.
A run too short for the filter's padding is filtered with shorter padding; runs of 1-3
frames are left as they are.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from posecam.errors import InputError
from posecam.results import DEFAULT_FPS, Frame, Person, Recording

METHODS = ("butterworth", "one_euro")
MIN_RUN = 4                     # frames; shorter runs are not filtered


@dataclass
class SmoothOptions:
    method: str = "butterworth"     # "butterworth" or "one_euro"
    cutoff_hz: float = 6.0          # butterworth: low-pass cut-off
    order: int = 4                  # butterworth: order of the two passes together (even)
    min_cutoff_hz: float = 1.0      # one_euro: cut-off at rest
    beta: float = 0.05              # one_euro: cut-off growth per mm/s of speed
    d_cutoff_hz: float = 1.0        # one_euro: cut-off of the speed estimate

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise InputError(f"smoothing method must be one of {', '.join(METHODS)}, got {self.method!r}")
        if self.cutoff_hz <= 0 or self.min_cutoff_hz <= 0 or self.d_cutoff_hz <= 0 or self.beta < 0:
            raise InputError("smoothing cut-offs must be positive and beta non-negative")
        if self.order < 2 or self.order % 2:
            raise InputError(f"butterworth order must be even and at least 2, got {self.order}")


def runs(valid: np.ndarray) -> list[slice]:
    """Slices of the unbroken True runs of a 1-D boolean array."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], valid.astype(np.int8), [0]])))
    return [slice(a, b) for a, b in zip(edges[::2], edges[1::2])]


def butter_lowpass(order: int, cutoff: float) -> tuple[np.ndarray, np.ndarray]:
    """Digital Butterworth low-pass (b, a) of `order`, `cutoff` as a fraction of the Nyquist
    rate: the analog prototype's poles, pre-warped, through the bilinear transform (scipy's
    `butter(order, cutoff)`)."""
    m = np.arange(-order + 1, order, 2)
    warped = 4.0 * np.tan(np.pi * cutoff / 2.0)
    poles = -warped * np.exp(1j * np.pi * m / (2 * order))          # analog, s-plane
    gain = warped ** order / np.real(np.prod(4.0 - poles))
    a = np.real(np.poly((4.0 + poles) / (4.0 - poles)))             # bilinear transform, fs = 2
    b = gain * np.real(np.poly(-np.ones(order)))                     # all zeros at z = -1
    return b, a


def _lfilter(b: np.ndarray, a: np.ndarray, x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """IIR filter along axis 0 (direct form II transposed) from the state `z` (n-1, ...)."""
    y = np.empty_like(x)
    z = z.copy()
    for i in range(len(x)):
        y[i] = b[0] * x[i] + z[0]
        z[:-1] = b[1:-1, None] * x[i] + z[1:] - a[1:-1, None] * y[i]
        z[-1] = b[-1] * x[i] - a[-1] * y[i]
    return y


def _filtfilt(b: np.ndarray, a: np.ndarray, x: np.ndarray, padlen: int) -> np.ndarray:
    """Forward-backward filtering of (F, C) `x`, odd extension by `padlen` frames at each end and
    steady-state initial conditions (scipy's `filtfilt(b, a, x, axis=0, padlen=padlen)`)."""
    n = len(a)
    companion = np.eye(n - 1, k=-1)
    companion[0] = -a[1:]
    zi = np.linalg.solve(np.eye(n - 1) - companion.T, b[1:] - a[1:] * b[0])[:, None]
    ext = np.concatenate([2 * x[:1] - x[padlen:0:-1], x, 2 * x[-1:] - x[-2:-padlen - 2:-1]])
    y = _lfilter(b, a, ext, zi * ext[0])
    y = _lfilter(b, a, y[::-1], zi * y[-1])[::-1]
    return y[padlen:len(y) - padlen]


def butterworth(x: np.ndarray, fps: float, cutoff_hz: float = 6.0, order: int = 4) -> np.ndarray:
    """Zero-phase low-pass of (F, ...) `x` along frames; NaN frames split it into runs."""
    x = np.asarray(x, dtype=float)
    out = x.copy()
    nyquist = fps / 2.0
    if cutoff_hz >= nyquist:
        return out
    b, a = butter_lowpass(order // 2, cutoff_hz / nyquist)
    flat, res = x.reshape(len(x), -1), out.reshape(len(x), -1)
    valid = np.isfinite(flat)
    masks, group = np.unique(valid, axis=1, return_inverse=True)    # columns missing in the same frames
    for g in range(masks.shape[1]):
        cols = np.flatnonzero(group.ravel() == g)
        for run in runs(masks[:, g]):
            n = run.stop - run.start
            if n >= MIN_RUN:
                res[run, cols] = _filtfilt(b, a, flat[run][:, cols], min(3 * len(a), n - 1))
    return out


def one_euro(x: np.ndarray, fps: float, min_cutoff_hz: float = 1.0, beta: float = 0.05,
             d_cutoff_hz: float = 1.0) -> np.ndarray:
    """One-Euro filter of (F, ...) `x` along frames; it restarts after every NaN gap."""
    x = np.asarray(x, dtype=float)
    out = x.copy()
    dt = 1.0 / fps

    def alpha(cutoff):
        tau = 1.0 / (2 * np.pi * cutoff)
        return 1.0 / (1.0 + tau / dt)

    prev = np.full(x.shape[1:], np.nan)
    d_prev = np.zeros(x.shape[1:])
    for i in range(len(x)):
        cur = x[i]
        fresh = ~np.isfinite(prev)
        d = np.where(fresh, 0.0, (cur - prev) / dt)
        d_hat = alpha(d_cutoff_hz) * d + (1 - alpha(d_cutoff_hz)) * d_prev
        a = alpha(min_cutoff_hz + beta * np.abs(d_hat))
        filtered = np.where(fresh, cur, a * cur + (1 - a) * prev)
        out[i] = filtered
        prev, d_prev = filtered, np.where(np.isfinite(d_hat), d_hat, 0.0)
    return out


def smooth_array(x: np.ndarray, fps: float, options: SmoothOptions) -> np.ndarray:
    """(F, ...) trajectory, NaN where missing -> the same shape, smoothed."""
    if options.method == "butterworth":
        return butterworth(x, fps, options.cutoff_hz, options.order)
    return one_euro(x, fps, options.min_cutoff_hz, options.beta, options.d_cutoff_hz)


def smooth_recording(rec: Recording, options: SmoothOptions | None = None) -> Recording:
    """A copy of `rec` whose people's 2D and 3D keypoints are smoothed along each track id, each
    person keeping the keypoints as observed (`Person.observed`).

    A still image (one frame) comes back unchanged; a recording without a frame rate is taken
    at `DEFAULT_FPS`."""
    options = options or SmoothOptions()
    if len(rec.frames) < 2:
        return dataclasses.replace(rec, frames=[dataclasses.replace(f, people=list(f.people)) for f in rec.frames])
    fps = rec.fps or DEFAULT_FPS
    smoothed: dict[int, Person] = {}     # id() of each person -> the person smoothed
    for track in rec.tracks():
        uv, xyz = (smooth_array(a, fps, options) for a in (track.keypoints_2d, track.keypoints_3d))
        for r in np.flatnonzero(track.present):
            person = track.people[r]
            seen_uv, seen_xyz = person.observed()   # what was observed stays, for the estimators that need it
            smoothed[id(person)] = dataclasses.replace(person, keypoints_2d=uv[r], keypoints_3d=xyz[r],
                                                       observed_2d=seen_uv, observed_3d=seen_xyz)
    return dataclasses.replace(rec, frames=[dataclasses.replace(f, people=[smoothed.get(id(p), p) for p in f.people])
                                            for f in rec.frames])


class StreamingSmoother:
    """`smooth_recording` for a stream of frames, in bounded memory: push each frame as it comes,
    take the smoothed frames that come back (`margin` to `block + margin` frames late), and
    `flush()` at the end. Each frame is smoothed inside a window reaching at least `margin`
    frames before and after it (or to the ends of the video); the filters forget faster than
    that (2 s at 60 fps), so the result is the whole video's smoothing to float precision."""

    def __init__(self, rec: Recording, options: SmoothOptions | None = None, block: int = 600, margin: int = 120):
        self.rec, self.options, self.block, self.margin = rec, options, block, margin
        self._frames: list[Frame] = []    # the window: raw frames, the first `_done` already given out
        self._done = 0

    def push(self, frame: Frame) -> list[Frame]:
        self._frames.append(frame)
        if len(self._frames) - self._done < self.block + self.margin:
            return []
        return self._emit(self.block)

    def flush(self) -> list[Frame]:
        return self._emit(len(self._frames) - self._done)

    def _emit(self, n: int) -> list[Frame]:
        if n <= 0:
            return []
        smoothed = smooth_recording(dataclasses.replace(self.rec, frames=self._frames), self.options).frames
        out = smoothed[self._done:self._done + n]
        keep_from = max(0, self._done + n - self.margin)   # the past context of the next window
        self._frames = self._frames[keep_from:]
        self._done = self._done + n - keep_from
        return out
