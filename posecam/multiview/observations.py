"""The multi-view data: people's keypoints and monocular poses as the views saw them.

    ViewTrack       one person id of one view, over that view's own frames: what a view's
                    recording gives (`tracks_of`), the unit the association links
    PersonTracks    one person across views: the view tracks the association linked
    Observations    one person (or several, side by side along the frames) seen by V views, in the
                    reference camera's frames (offsets applied): what every stage after the
                    association works on (sync, the cameras, left/right, fusion, the report)

    Take            the checked views of one take as every stage reads them: names, the views'
                    own cameras as their monocular poses assumed them (CameraCalibrations with
                    no pose, `assumed_cameras`), tracks, lengths

Offsets (`shift`): view c's frame i + o shows the reference's frame i (posecam.multiview.sync).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from posecam.geometry.camera import CameraCalibration
from posecam.analysis.filters import butterworth
from posecam.geometry.triangulate import MIN_CONFIDENCE, observation_weights
from posecam.multiview.policy import TAKE
from posecam.results import DEFAULT_FPS, Recording


def shift(a: np.ndarray, offset: float, length: int, fill=np.nan) -> np.ndarray:
    """Frames offset .. offset + length - 1 of `a` (F, ...), padded with `fill` outside; a
    fractional offset interpolates linearly between the two frames around it (where both have
    a value; `fill` 0 marks confidences, which take the smaller of the two)."""
    out = np.full((length,) + a.shape[1:], fill, dtype=float)
    i = np.arange(length)
    lo = int(np.floor(offset))
    frac = float(offset - lo)
    j = i + lo
    if frac < 1e-6:
        ok = (j >= 0) & (j < len(a))
        out[i[ok]] = a[j[ok]]
        return out
    ok = (j >= 0) & (j + 1 < len(a))
    lo_v, hi_v = a[j[ok]].astype(float), a[j[ok] + 1].astype(float)
    out[i[ok]] = np.minimum(lo_v, hi_v) if fill == 0.0 else (1 - frac) * lo_v + frac * hi_v
    return out


def lowpass(a: np.ndarray, seen: np.ndarray, fps: float, hz: float) -> np.ndarray:
    """(F, J, D) tracks low-passed in time (posecam.analysis.filters.butterworth at `hz`: 2nd order,
    forwards and back), each joint's gaps bridged where it is not `seen` (F, J), held before
    and after; NaN for joints seen in fewer than TAKE.lowpass_frames frames."""
    out = np.full(a.shape, np.nan)
    idx = np.arange(len(a))
    kept = [k for k in range(a.shape[1]) if seen[:, k].sum() >= TAKE.lowpass_frames]
    if not kept:
        return out
    filled = np.stack([np.stack([np.interp(idx, idx[seen[:, k]], a[seen[:, k], k, d]) for d in range(a.shape[2])],
                                axis=1) for k in kept], axis=1)
    out[:, kept] = butterworth(filled, fps, hz, order=4)       # every joint at once: one pass over the frames
    return out


@dataclass
class TimedKeypoints:
    """People's 2D keypoints seen by V views at S whole-frame offsets about each view's own:
    sample s of view v at the reference's frame i is the view's frame i + base[v] + s, so that
    a continuous offset o in [base + 1, base + S - 2] is interpolated (Catmull-Rom: `at`)
    between samples; what lets the bundle adjustment move the offsets (posecam.multiview.bundle).
    Low-passed in time, every view alike: interpolating raw keypoints averages two frames' noise
    at a fractional offset, which would bias the reprojection error there low."""

    uv: np.ndarray              # (V, S, F, J, 2), NaN where unseen
    conf: np.ndarray            # (V, S, F, J)
    base: np.ndarray            # (V,) int

    def take(self, views: list[int]) -> "TimedKeypoints":
        return TimedKeypoints(self.uv[views], self.conf[views], self.base[views])

    def frames(self, index: np.ndarray) -> "TimedKeypoints":
        return TimedKeypoints(self.uv[:, :, index], self.conf[:, :, index], self.base)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(V,) the offsets that the samples can interpolate."""
        return self.base + 1.0, self.base + self.uv.shape[1] - 2.0

    def at(self, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(V, F, J, 2) keypoints and (V, F, J) confidences at the offsets (V,)."""
        v, s, f, j, _ = self.uv.shape
        t = np.repeat(np.asarray(offsets, float) - self.base, f * j)
        uv, _ = catmull_rom(held(self.uv.transpose(0, 2, 3, 1, 4).reshape(-1, s, 2)), t)
        return uv.reshape(v, f, j, 2), self.conf_at(np.asarray(offsets, float))

    def conf_at(self, offsets: np.ndarray) -> np.ndarray:
        """(V, F, J) confidence at the offsets: the smaller of the two samples around each."""
        s = np.clip(np.floor(offsets - self.base).astype(int), 1, self.uv.shape[1] - 3)
        v = np.arange(len(s))
        frac = offsets - self.base - s
        return np.where((frac > 1e-6)[:, None, None], np.minimum(self.conf[v, s], self.conf[v, s + 1]), self.conf[v, s])


def held(samples: np.ndarray) -> np.ndarray:
    """(N, S, D) samples with each NaN run filled from the nearest finite sample before it, else
    after it (NaN where a row has none)."""
    out = samples.copy()
    for s in range(1, out.shape[1]):
        out[:, s] = np.where(np.isnan(out[:, s]), out[:, s - 1], out[:, s])
    for s in range(out.shape[1] - 2, -1, -1):
        out[:, s] = np.where(np.isnan(out[:, s]), out[:, s + 1], out[:, s])
    return out


def catmull_rom(samples: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Samples (N, S, D) at times 0..S-1 evaluated at t (N,) in [1, S-2], the cubic through the
    four samples around each (Catmull-Rom: C1, exact at the samples); (N, D) values and their
    derivatives d/dt."""
    k = np.clip(np.floor(t).astype(int), 1, samples.shape[1] - 3)
    u = (t - k)[:, None]
    n = np.arange(len(t))
    p0, p1, p2, p3 = (samples[n, k + d] for d in (-1, 0, 1, 2))
    a, b, c = -p0 + 3 * p1 - 3 * p2 + p3, 2 * p0 - 5 * p1 + 4 * p2 - p3, p2 - p0
    return 0.5 * (((a * u + b) * u + c) * u + 2 * p1), 0.5 * ((3 * a * u + 2 * b) * u + c)


@dataclass
class ViewTrack:
    """One person id of one view, over that view's own frames (NaN / conf 0 where unseen)."""

    view: int
    ids: tuple[int, ...]        # person ids in the view's recording (several after an id switch)
    uv: np.ndarray              # (F_view, J, 2) pixels
    xyz: np.ndarray             # (F_view, J, 3) camera coordinates, mm
    conf: np.ndarray            # (F_view, J)
    score: np.ndarray           # (F_view,) detection score, 0 where unseen

    @property
    def seen(self) -> np.ndarray:
        """(F_view,) frames where the track has at least one joint."""
        return self.conf.max(axis=1) > 0


@dataclass
class PersonTracks:
    """One person across views: its view tracks (at most one per view at any frame)."""

    tracks: list[ViewTrack]

    @property
    def views(self) -> list[int]:
        return sorted({t.view for t in self.tracks})

    def in_view(self, view: int, n_frames: int) -> ViewTrack:
        """This person in `view`'s own n_frames, its tracks there merged into one."""
        j = self.tracks[0].conf.shape[1]
        uv, xyz = np.full((n_frames, j, 2), np.nan), np.full((n_frames, j, 3), np.nan)
        conf, score = np.zeros((n_frames, j)), np.zeros(n_frames)
        ids = []
        for t in self.tracks:
            if t.view == view:
                s = t.seen & (conf.max(axis=1) == 0)
                uv[s], xyz[s], conf[s], score[s] = t.uv[s], t.xyz[s], t.conf[s], t.score[s]
                ids += t.ids
        return ViewTrack(view, tuple(ids), uv, xyz, conf, score)


@dataclass
class Observations:
    """People seen by V views, in the reference camera's frames (offsets applied)."""

    uv: np.ndarray              # (V, F, J, 2)
    xyz: np.ndarray             # (V, F, J, 3) each view's camera coordinates
    conf: np.ndarray            # (V, F, J), 0 where the view does not see the person
    score: np.ndarray           # (V, F)
    _root_depth: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        v, f, j = self.conf.shape
        for name, a, shape in (("uv", self.uv, (v, f, j, 2)), ("xyz", self.xyz, (v, f, j, 3)),
                               ("score", self.score, (v, f))):
            if a.shape != shape:
                raise ValueError(f"Observations.{name}: expected {shape}, got {a.shape}")

    @classmethod
    def of(cls, person: PersonTracks, lengths: list[int], offsets: list[float], n: int) -> "Observations":
        """The person in every view (lengths: each view's frames), shifted by the offsets
        (posecam.multiview.sync) onto the reference's n frames."""
        parts = [person.in_view(v, length) for v, length in enumerate(lengths)]
        return cls(*(np.stack([shift(getattr(p, k), o, n, fill) for p, o in zip(parts, offsets)])
                     for k, fill in (("uv", np.nan), ("xyz", np.nan), ("conf", 0.0), ("score", 0.0))))

    @classmethod
    def side_by_side(cls, people: list["Observations"]) -> "Observations":
        """Several people's observations (the same views) as one, along the frame axis."""
        return cls(*(np.concatenate([getattr(p, k) for p in people], axis=1) for k in ("uv", "xyz", "conf", "score")))

    def take(self, views: list[int]) -> "Observations":
        return Observations(self.uv[views], self.xyz[views], self.conf[views], self.score[views])

    def frames(self, step: int) -> "Observations":
        """Every `step`-th frame."""
        return Observations(self.uv[:, ::step], self.xyz[:, ::step], self.conf[:, ::step], self.score[:, ::step])

    def weights(self, min_conf: float = MIN_CONFIDENCE) -> np.ndarray:
        """(V, F, J) confidence as a weight; 0 for missing joints, conf < min_conf, or depth <= 0."""
        w = observation_weights(self.uv, self.conf, min_conf)
        return np.where(np.isfinite(self.xyz).all(axis=-1) & (np.nan_to_num(self.xyz[..., 2]) > 0), w, 0.0)

    def root_depth(self) -> np.ndarray:
        """(V, F) confidence-weighted mean depth of each frame's joints: the part that scales
        with f (posecam.multiview.consensus); computed once (the arrays are never changed in place)."""
        if self._root_depth is None:
            w = observation_weights(self.uv, self.conf, 0.0)
            w = np.where(np.isfinite(self.xyz[..., 2]), w, 0.0)
            total = w.sum(axis=-1)
            z = (np.nan_to_num(self.xyz[..., 2]) * w).sum(axis=-1)
            self._root_depth = np.where(total > 0, z / np.maximum(total, 1e-12), np.nan)
        return self._root_depth


def assumed_cameras(names: list[str], recordings: list[Recording]) -> list[CameraCalibration]:
    """Each view's camera as its monocular poses assumed it: name, image size, the intrinsics
    the poses were made with; no pose yet."""
    return [CameraCalibration(name, (r.width, r.height), r.intrinsics) for name, r in zip(names, recordings)]


def tracks_of(rec: Recording, view: int, min_frames: int = TAKE.min_track_frames) -> list[ViewTrack]:
    """Every person id of `rec` seen in at least `min_frames` frames, longest first (then by
    first appearance), as observed (`Track`, the keypoints before smoothing, which the estimators
    downstream need, not the smoothed ones that are shown); a pose with doubts
    (posecam.analysis.doubts) counts as unseen."""
    n, j = len(rec.frames), len(rec.joints)
    tracks = []
    for t in rec.tracks():
        sound = np.array([p is not None and not p.doubts for p in t.people])
        if sound.sum() < min_frames:
            continue
        rows = t.rows[sound]
        uv, xyz = np.full((n, j, 2), np.nan), np.full((n, j, 3), np.nan)
        conf, score = np.zeros((n, j)), np.zeros(n)
        uv[rows], xyz[rows], conf[rows] = t.observed_2d[sound], t.observed_3d[sound], t.confidence[sound]
        score[rows] = [p.score for p, s in zip(t.people, sound) if s]
        first = t.people[int(np.argmax(sound))]
        order = (rows[0], next(k for k, q in enumerate(rec.frames[rows[0]].people) if q is first))
        tracks.append((order, ViewTrack(view, (t.id,), uv, xyz, conf, score)))
    return [v for _, v in sorted(tracks, key=lambda o: (-int(o[1].seen.sum()), o[0]))]


@dataclass
class Take:
    """The views of one take, checked (posecam.multiview.take_check), as every stage reads them."""

    names: list[str]                     # camera names: the input file stems, made unique
    assumed: list[CameraCalibration]     # each view's camera as its monocular poses assumed it
    tracks: list[list[ViewTrack]]        # each view's people (`tracks_of`)
    lengths: list[int]                   # each view's frames
    joints: tuple[str, ...]
    reference: int                       # the view whose camera and frames the others are put in
    fps: float                           # the reference's frame rate (DEFAULT_FPS where it has none)
    warnings: list[str] = field(default_factory=list)   # what checking the views found (posecam.multiview.take_check)

    @classmethod
    def of(cls, names: list[str], recordings: list[Recording], reference: int) -> "Take":
        return cls(names, assumed_cameras(names, recordings), [tracks_of(r, v) for v, r in enumerate(recordings)],
                   [len(r.frames) for r in recordings], recordings[reference].joints, reference,
                   recordings[reference].fps or DEFAULT_FPS)

    def observations(self, people: list[PersonTracks], offsets: list[float], views: list[int]) -> list[Observations]:
        """Each person in the `views`, at the offsets, in the reference's frames."""
        n = self.lengths[self.reference]
        return [Observations.of(p, self.lengths, offsets, n).take(views) for p in people]

    def timed(self, people: list[PersonTracks], offsets: list[float], window: int, hz: float,
              min_conf: float) -> TimedKeypoints:
        """Every view's keypoints of the people (side by side along the frames, as
        Observations.side_by_side puts them), low-passed at `hz` (`lowpass`; a joint seen
        below min_conf is a gap), at whole-frame offsets `window` frames either way of each
        view's offset (TimedKeypoints)."""
        n = self.lengths[self.reference]
        base = np.round(offsets).astype(int) - window - 1
        steps = 2 * window + 3
        uv = np.full((len(self.names), steps, n * len(people), len(self.joints), 2), np.nan)
        conf = np.zeros(uv.shape[:-1])
        for v, length in enumerate(self.lengths):
            for q, person in enumerate(people):
                seen = person.in_view(v, length)
                track, c = seen.uv, seen.conf
                smooth = lowpass(track, (c >= min_conf) & np.isfinite(track).all(axis=-1), self.fps, hz)
                c = np.where(np.isfinite(smooth).all(axis=-1), c, 0.0)
                for s in range(steps):
                    uv[v, s, q * n:(q + 1) * n] = shift(smooth, base[v] + s, n)
                    conf[v, s, q * n:(q + 1) * n] = shift(c, base[v] + s, n, 0.0)
        return TimedKeypoints(uv, conf, base)
