"""Metric scale of every person: one scale per track, from a known height, the floor, or the pose
model's adult-sized skeleton.

    from posecam.scale.metric import MetricOptions, scale_recording
    rec = scale_recording(rec, MetricOptions(heights=Heights.parse(["1.72,1.21"])))

The pose model's metric skeleton has an adult's size, and the root translation is solved from
it and the 2D keypoints (posecam.geometry.lift). That solve is linear and homogeneous in the
skeleton: scaling the root-relative skeleton by s scales the whole camera-space pose by s about
the camera centre and leaves the 2D keypoints where they are. So a person's size can be fixed
after the pose model, on the stream of frames, by multiplying each pose by its scale:
- each frame's skeleton is brought to its track's height (the median over the track's frames),
  so a person's size no longer breathes from frame to frame;
- the track's height is the one given (`--height`), or the one the floor gives (static camera:
  everyone's feet on one plane fixes each track's size relative to the others; the adult-sized
  people are brought to the pose model's size), or else the pose model's size: the one stature
  its skeletons have whoever the person (MODEL_STATURE), not the track's own, which differs from
  it by the model's error.
Frames are held back `delay` frames, so that the first ones are scaled with their track's
estimate too; the statistics of a track are a bounded, evenly thinned sample of its frames.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from posecam.errors import InputError
from posecam.geometry.camera import DEFAULT_FOCAL_SD, Intrinsics
from posecam.geometry.floor import Floor, FloorFit, fit_floor, robust_sd
from posecam.geometry.lift import place_on_keypoints
from posecam.results import Frame, Person, Recording
from posecam.scale.heights import Heights
from posecam.scale.lens import LensFit, focal_from_people
from posecam.scale.policy import SCALE
from posecam.scale.stature import ANKLE_OF_STATURE, down_and_ankles, segments, stature
from posecam.skeleton import MIN_CONFIDENCE, skeleton_of

# The pose model's skeleton has one size, whoever the person: the statures of its skeletons (the
# chain above) over the pedestrians of vtest.avi (tracks of 20 frames and more, each its median)
# spread by 1.5 % about their median, no more than one 1.72 m adult's do over the 8 lab views of
# the Pose2Sim takes (1.63-1.69 m), and a child's are as tall (1.66-1.71 m). So a track's own
# skeleton size is the model's error for that view, not the person's size (the lab views whose
# track is shorter are the ones placed too near): with nothing else to scale them, tracks are
# brought to the model's size. bench/bench_depth.py measures it again (m; models not listed keep
# their tracks' own sizes). A track too far from it, or measured on too few of its frames, is
# left unmeasured (`TrackScale.measured`; SCALE.size_off, SCALE.seen_share).
MODEL_STATURE = {"blazepose-full": 1.678, "blazepose-lite": 1.647}
# The joints that move the most with the pose (the arms: elbows, wrists, hands) also move the
# root's depth most when the pose model misplaces them in depth: jumping jacks on the spot swing
# the root's depth with the arms. Each frame's root is placed again on the trunk and legs (the
# CORE roles: the same landmarks in every skeleton, so both skeletons keep one root), where at
# least SCALE.core_joints of them are confident.
CORE = tuple(f"{side}_{joint}" for side in ("r", "l") for joint in ("shoulder", "hip", "knee", "ankle"))


@dataclass
class MetricOptions:
    heights: Heights = field(default_factory=Heights)   # known heights (posecam.scale.heights)
    floor: bool = True          # fit the floor (static camera) and scale each track to it
    lens: bool = True           # with the default lens, take the focal length from the people where they pin it
    delay: int = 120            # frames held back before they are given out (the lens is decided on them)

    def __post_init__(self) -> None:
        if self.delay < 0:
            raise InputError(f"delay must be 0 or more frames, got {self.delay}")


class _Sample:
    """An evenly thinned sample of a stream of rows, at most `size` kept (every 2^k-th row)."""

    def __init__(self, size: int = SCALE.samples):
        self.size, self.stride, self.seen, self.rows = size, 1, 0, []

    def add(self, row) -> None:
        if self.seen % self.stride == 0:
            self.rows.append(row)
            if len(self.rows) > self.size:
                self.rows, self.stride = self.rows[::2], self.stride * 2
        self.seen += 1


@dataclass
class _Track:
    frames: int = 0                                       # frames the track is in
    heights: _Sample = field(default_factory=_Sample)     # per-frame stature (mm)
    feet: _Sample = field(default_factory=_Sample)        # (stature, ankles (2, 3)) of frames with the feet seen
    downs: _Sample = field(default_factory=_Sample)       # down directions of upright frames
    upright: _Sample = field(default_factory=lambda: _Sample(SCALE.lens_samples))   # (head, feet) px of upright frames

    _cache: tuple = (-1, np.nan, SCALE.model_sd)        # (heights seen, stature, breathing)

    def _statistics(self) -> tuple[float, float]:
        if self._cache[0] != self.heights.seen:
            h = np.asarray(self.heights.rows)
            mid = float(np.median(h)) if len(h) else np.nan
            spread = robust_sd(h) / mid if len(h) >= 3 else SCALE.model_sd
            self._cache = (self.heights.seen, mid, spread)
        return self._cache[1], self._cache[2]

    @property
    def stature(self) -> float:
        """The track's height (mm): the median of its frames' statures."""
        return self._statistics()[0]

    @property
    def breathing(self) -> float:
        """Relative spread of the track's per-frame statures (1.4826 MAD / median)."""
        return self._statistics()[1]


@dataclass(frozen=True)
class TrackScale:
    """What a track's people are multiplied by, and why."""

    stature: float              # mm: the track's skeleton height before scaling (the pose model's)
    scale: float                # the track's scale (its people's height used / stature)
    source: str                 # "given", "given, rank K", "floor" or "model"
    estimated: float            # m: the height estimated without a given one (floor, else model)
    estimated_sd: float         # m
    relative_sd: float          # relative uncertainty of the scale used
    measured: bool = True       # False: never seen whole enough to measure; `stature` is the pose model's size


class MetricStage:
    """Scale each person of a stream of frames by their track's scale: push each frame as it
    comes, take the frames that come back (`delay` frames late), `flush()` at the end. After the
    flush, `floor` is the ground plane (or None, and `floor_refused` says why), `lens` the focal
    length the people give, and `notes` the warnings for the user. The recording it is given
    (its header: joints, model, image size, intrinsics) is only read.

    With the default lens (`rec.intrinsics.source == "default"`), the people's focal length
    (posecam.scale.lens.focal_from_people) is tried on the first `delay` frames, before any
    is given out; where it is pinned, `intrinsics` (the lens of the frames given out) becomes it
    (source "people") and every person's root is solved again with it."""

    def __init__(self, rec: Recording, options: MetricOptions | None = None):
        self.rec, self.options = rec, options or MetricOptions()
        self._tracks: dict[int, _Track] = {}
        self._pending: list[Frame] = []
        self._fit: FloorFit | None = None
        self._since_fit = SCALE.refit_every     # frames observed since the floor was last fitted
        self.floor: Floor | None = None
        self.floor_refused = ""
        self.lens: LensFit | None = None
        self.notes: list[str] = []
        self.intrinsics = rec.intrinsics        # the lens of the frames given out
        self._k: Intrinsics | None = None       # the people's lens, once taken: every pose is solved again with it
        self._frames_seen = 0
        self._last: dict[int, TrackScale] = {}  # the scales of the last frames given out
        self._measurable = segments(rec.joints) is not None
        self._model_mm = 1000.0 * MODEL_STATURE[rec.model] if rec.model in MODEL_STATURE else None
        self._core = np.zeros(len(rec.joints))
        if self._measurable:   # posecam's skeletons
            skeleton = skeleton_of(rec.joints)
            self._core[[i for role in CORE for i in skeleton.role(role)]] = 1.0

    def push(self, frame: Frame) -> list[Frame]:
        self._since_fit += 1
        self._frames_seen += 1
        if self._k is not None:
            frame = self._relensed(frame)
        if self._measurable:
            for p in frame.people:
                self._observe(p)
        self._pending.append(frame)
        if len(self._pending) <= self.options.delay:
            return []
        return self._emit(len(self._pending) - self.options.delay)

    def flush(self) -> list[Frame]:
        self._since_fit = SCALE.refit_every     # the last fit sees every frame
        out = self._emit(len(self._pending))
        if self._k is None:
            self._check_lens()
        self.notes += self.options.heights.doubts({tid: (ts.estimated, ts.estimated_sd) for tid, ts in self._last.items()})
        if self.floor_refused and self._tracks and self._frames_seen > 1:
            size = (f"everyone has the pose model's size, an adult's ({self._model_mm / 1000:.2f} m): a child or anyone "
                    f"far from it is placed too far or too near in proportion (give --height)"
                    if self._model_mm else "each person keeps their track's own scale")
            self.notes.append(f"no floor: {self.floor_refused}; {size}")
        return out

    def _lens_fit(self) -> LensFit | None:
        """The people's focal length from the upright frames so far; None where it is not asked
        for (a lens was given, `lens` off) or nobody stood upright."""
        k = self.rec.intrinsics
        if not (self.options.lens and self._measurable and k is not None and k.source == "default"):
            return None
        rows = [(tid, head, feet) for tid, t in self._tracks.items() for head, feet in t.upright.rows]
        if not rows:
            return None
        return focal_from_people(np.array([r[1] for r in rows]), np.array([r[2] for r in rows]),
                                 np.array([r[0] for r in rows]), np.array([k.cx, k.cy]), self.rec.height)

    def _decide_lens(self) -> None:
        """Before the first frame goes out: the people's focal length in place of the default
        lens, where they pin it (the frames so far are solved again and observed anew)."""
        self.lens = fit = self._lens_fit()
        if fit is None or fit.focal is None:
            return
        k = self.rec.intrinsics
        self._k = self.intrinsics = Intrinsics(fit.focal, fit.focal, k.cx, k.cy, f"people (+-{fit.sd:.0f} px)")
        self._pending = [self._relensed(f) for f in self._pending]
        self._tracks, self._since_fit = {}, SCALE.refit_every
        for f in self._pending:
            for p in f.people:
                self._observe(p)

    def _check_lens(self) -> None:
        """At the end, with the default lens kept: the people's focal length over every frame,
        and a note where it disagrees with the default lens (or pins it only now)."""
        fit = self._lens_fit()
        if fit is None:
            return
        self.lens, k = fit, self.rec.intrinsics
        if fit.focal is not None:
            self.notes.append(f"the people pin the focal length at {fit.focal:.0f} +- {fit.sd:.0f} px over the whole "
                              f"input (the default lens has {k.fx:.0f}; the first {self.options.delay} frames did not "
                              f"pin it): run again with --fx {fit.focal:.0f}")
        elif np.isfinite(fit.estimate) and abs(fit.estimate - k.fx) > SCALE.lens_disagrees * fit.sd:
            self.notes.append(f"the default lens (f = {k.fx:.0f} px) disagrees with the people's geometry "
                              f"(f = {fit.estimate:.0f} +- {fit.sd:.0f} px from their verticals and horizon): "
                              f"depths may be {fit.estimate / k.fx:.1f}x off; give --fx or --intrinsics")

    def _relensed(self, frame: Frame) -> Frame:
        """The frame's people lifted again through the people's lens: by the estimator's lifter
        (`Person.relift`), else (poses read from a file) their metric pose placed on their 2D
        keypoints, as the landmark models' lift places it."""
        people = [dataclasses.replace(p, keypoints_3d=p.relift(self._k) if p.relift else
                                      place_on_keypoints(p.keypoints_3d, p.keypoints_2d, p.confidence, self._k))
                  for p in frame.people]
        return dataclasses.replace(frame, people=people)

    def _observe(self, p: Person) -> None:
        t = self._tracks.setdefault(p.id, _Track())
        t.frames += 1
        h = float(stature(p.keypoints_3d, p.confidence, self.rec.joints))
        if not np.isfinite(h):
            return
        t.heights.add(h)
        down, ankles = down_and_ankles(p.keypoints_3d, self.rec.joints)
        t.feet.add((h, ankles))
        if down is not None:
            t.downs.add(down)
            seg = segments(self.rec.joints)
            ends = [list(seg["head"]), [leg[2] for leg in seg["legs"]]]
            if min(p.confidence[i].min() for i in ends) >= MIN_CONFIDENCE:
                t.upright.add((p.keypoints_2d[ends[0]].mean(axis=0), p.keypoints_2d[ends[1]].mean(axis=0)))

    def _floor_fit(self) -> FloorFit | None:
        """The floor from every track's contacts, each frame's brought to its track's stature:
        the lower ankle along the people's vertical, moved down to the sole."""
        downs = [d for t in self._tracks.values() for d in t.downs.rows]
        if not downs:
            return FloorFit(None, {}, {}, "nobody stands upright with the legs and head seen")
        vertical = np.median(downs, axis=0)
        vertical /= np.linalg.norm(vertical)
        contacts, measured = {}, self._measured()
        for tid, t in self._tracks.items():
            if len(t.feet.rows) < SCALE.min_track_contacts or tid not in measured:
                continue
            h_track = t.stature
            pts = []
            for h, ankles in t.feet.rows:
                lower = ankles[np.argmax(ankles @ vertical)] * (h_track / h)
                pts.append(lower + ANKLE_OF_STATURE * h_track * vertical)
            contacts[tid] = np.array(pts)
        return fit_floor(contacts, np.array(downs))

    def _measured(self) -> dict[int, float]:
        """The statures (mm) of the tracks measured so far: seen whole on at least SCALE.seen_share of
        their frames, and at the pose model's size within SCALE.size_off where it is known."""
        return {tid: t.stature for tid, t in self._tracks.items()
                if np.isfinite(t.stature) and t.heights.seen >= SCALE.seen_share * t.frames
                and (not self._model_mm or abs(t.stature / self._model_mm - 1.0) <= SCALE.size_off)}

    def _scales(self) -> dict[int, TrackScale]:
        """Every track's scale, from the statistics so far."""
        fit = self._fit
        if self.options.floor and self._since_fit >= SCALE.refit_every:
            fit = self._fit = self._floor_fit()
            self._since_fit = 0
        on_floor = fit is not None and fit.floor is not None
        measured = self._measured()
        # people never measured (legs out of view): the skeleton the pose model gave, at its size
        stat = {**dict.fromkeys(self._tracks, self._model_mm), **measured} if self._model_mm else measured
        # the pose model's scale: each track to the model's size (or, for a model not measured, its own)
        model = {tid: self._model_mm / h if self._model_mm else 1.0 for tid, h in stat.items()}
        # the floor's relative sizes; the adult-sized people at the pose model's size
        relative = {tid: fit.scales[tid] for tid in measured if on_floor and tid in fit.scales}
        gauge = 1.0
        if relative:
            size = {tid: relative[tid] * stat[tid] for tid in relative}
            adults = [tid for tid in size if size[tid] >= SCALE.adult_cluster * max(size.values())]
            gauge = float(np.median([model[tid] * stat[tid] for tid in adults])
                          / np.median([size[tid] for tid in adults]))
        estimated = {tid: (relative[tid] * gauge * h if tid in relative else self._model_mm or h) / 1000.0
                     for tid, h in stat.items()}
        low, high = SCALE.floor_stature_m
        odd = {tid: estimated[tid] for tid in relative if not low <= estimated[tid] <= high}
        if odd:   # feet out of view or off the ground (someone cut by the border, balancing): not a floor
            tid, metres = next(iter(odd.items()))
            fit = self._fit = FloorFit(None, {}, {}, f"the feet's plane would make person {tid} {metres:.2f} m tall")
            on_floor, relative, gauge = False, {}, 1.0
            estimated = {tid: (self._model_mm or h) / 1000.0 for tid, h in stat.items()}
        given = self.options.heights.assign(estimated) if self.options.heights else {}
        on_given = [given[tid][0] * 1000.0 / (relative[tid] * stat[tid]) for tid in given if tid in relative]
        used_gauge, gauge_sd = (float(np.median(on_given)), SCALE.given_sd) if on_given else (gauge, SCALE.model_sd)
        out = {}
        for tid, h in stat.items():
            est_sd = float(np.hypot(fit.scale_sd[tid], SCALE.model_sd)) if tid in relative else SCALE.model_sd
            if tid in given:
                metres, source = given[tid]
                scale, source, sd = metres * 1000.0 / h, source, SCALE.given_sd
            elif tid in relative:     # known heights on the floor fix its scale for the others too
                scale, source, sd = relative[tid] * used_gauge, "floor", float(np.hypot(fit.scale_sd[tid], gauge_sd))
            else:
                scale, source, sd = model[tid], "model", SCALE.model_sd
            out[tid] = TrackScale(h, scale, source, estimated[tid], estimated[tid] * est_sd, sd, tid in measured)
        if self.options.floor and fit is not None:
            self.floor = (dataclasses.replace(fit.floor, distance=fit.floor.distance * used_gauge,
                                              spread=fit.floor.spread * used_gauge) if on_floor else None)
            self.floor_refused = fit.reason
        return out

    def _emit(self, n: int) -> list[Frame]:
        if n <= 0:
            return []
        if self._frames_seen == len(self._pending):     # nothing given out yet
            self._decide_lens()
        scales = self._last = self._scales() if self._measurable else {}
        lens_sd = self._lens_sd()
        out = [self._scaled(f, scales, lens_sd) for f in self._pending[:n]]
        self._pending = self._pending[n:]
        return out

    def _lens_sd(self) -> float:
        """Relative uncertainty of the focal length the frames given out are placed through (every
        distance scales with it): the default lens's, the people's fit's, none for a lens given."""
        k = self.intrinsics
        if k is not None and k.source == "default":
            return DEFAULT_FOCAL_SD
        if self._k is not None and self.lens is not None and self.lens.focal:
            return self.lens.sd / self.lens.focal
        return 0.0

    def _scaled(self, frame: Frame, scales: dict[int, TrackScale], lens_sd: float) -> Frame:
        people = []
        for p in frame.people:
            ts = scales.get(p.id)
            if ts is None:
                people.append(p)
                continue
            h = float(stature(p.keypoints_3d, p.confidence, self.rec.joints)) if ts.measured else np.nan
            s = ts.scale * (ts.stature / h if np.isfinite(h) else 1.0)     # the track's height, then its scale
            breathing = self._tracks[p.id].breathing if ts.measured else 0.0
            xyz = self._on_core(p.keypoints_3d * s, p)
            depth = float(p.skeleton.root_point(xyz)[2])
            people.append(dataclasses.replace(
                p, keypoints_3d=xyz, height=ts.scale * ts.stature / 1000.0, height_source=ts.source,
                height_estimated=ts.estimated, height_sd=ts.estimated_sd,
                depth_sd=abs(depth) * float(np.linalg.norm([ts.relative_sd, breathing, lens_sd]))))
        return dataclasses.replace(frame, people=people)


    def _on_core(self, xyz: np.ndarray, p: Person) -> np.ndarray:
        """The pose `xyz` placed again on its 2D keypoints by the joints off the arms (see
        ARM_PARTS), through the lens of the frames given out; as it is where too few are seen."""
        weights = p.confidence * self._core
        k = self.intrinsics
        if k is None or (weights >= MIN_CONFIDENCE).sum() < SCALE.core_joints:
            return xyz
        return place_on_keypoints(xyz, p.keypoints_2d, weights, k)


def scale_recording(rec: Recording, options: MetricOptions | None = None) -> Recording:
    """A copy of `rec` with every person at their track's metric scale (and `floor` set when
    the feet support one, `intrinsics` the people's lens where they pin it): MetricStage over
    the whole recording."""
    stage = MetricStage(rec, options)
    frames = [out for f in rec.frames for out in stage.push(f)]
    frames += stage.flush()
    return dataclasses.replace(rec, frames=frames, floor=stage.floor, intrinsics=stage.intrinsics)
