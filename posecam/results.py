"""Result dataclasses: one person, one frame, one input (image, video or fused set of views)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from posecam.geometry.camera import Intrinsics
from posecam.geometry.floor import Floor
from posecam.skeleton import H36M, MIN_CONFIDENCE, Skeleton, skeleton_of

# Cut off at the waist, BlazePose still draws a whole body into the picture: the hips (the root) at
# full confidence on its lower part, the legs folded under them at a low one (scikit-image's
# astronaut; examples/balance.jpg cut at the waist). So the hips count as seen only with a knee.
HIP_ROLES = ("mid_hip", "r_hip", "l_hip")       # Skeleton.roles
KNEE_ROLES = ("r_knee", "l_knee")
DEFAULT_FPS = 30.0   # the frame rate of an image sequence, and of a video or a recording that gives none


@dataclass
class Person:
    """One person in one frame. Arrays follow the joint order of the recording, whose skeleton
    `skeleton` is (the 17 joints unless told: posecam's readers and estimators tell)."""

    id: int
    score: float
    bbox: np.ndarray            # (4,) x0, y0, x1, y1 in pixels
    keypoints_2d: np.ndarray    # (J, 2) u, v in pixels
    keypoints_3d: np.ndarray    # (J, 3) x, y, z in mm, camera (or world) coordinates
    confidence: np.ndarray      # (J,) in [0, 1]
    angles: dict[str, float] | None = None   # joint/segment angles in degrees (posecam.analysis.angles), when asked for
    # metric scale (posecam.scale.metric); NaN and "" where it was not fixed
    height: float = float("nan")            # m: the height the person's scale was fixed with
    height_source: str = ""                 # "given", "given, rank K", "floor" or "model"
    height_estimated: float = float("nan")  # m: the height estimated from the track, whatever was given
    height_sd: float = float("nan")         # m: its standard uncertainty
    depth_sd: float = float("nan")          # mm: standard uncertainty of the root's depth (z)
    doubts: tuple[str, ...] = ()            # why the pose may not be this person's (posecam.analysis.doubts); () sound
    views: int = 0                          # fused: the cameras in this pose (1: one camera's, not fused); 0: unknown
    # the keypoints as observed, before smoothing over time (posecam.analysis.filters): what fusion
    # estimates the cameras, the offsets and the fused pose from; None: keypoints_2d / _3d are those
    observed_2d: np.ndarray | None = None   # (J, 2) pixels
    observed_3d: np.ndarray | None = None   # (J, 3) mm
    skeleton: Skeleton = field(default=H36M, repr=False, compare=False)
    # the pose model's output of this person lifted through another lens (the estimator's lifter;
    # the metric stage's people's lens): (J, 3) mm; None for poses that were not predicted here
    relift: Callable[[Intrinsics], np.ndarray] | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if np.ndim(self.confidence) != 1:
            raise ValueError(f"Person.confidence: expected shape (J,), got {np.shape(self.confidence)}")
        j = len(self.confidence)
        for name, want in (("bbox", (4,)), ("keypoints_2d", (j, 2)), ("keypoints_3d", (j, 3)),
                           ("observed_2d", (j, 2)), ("observed_3d", (j, 3))):
            if getattr(self, name) is not None and np.shape(getattr(self, name)) != want:
                raise ValueError(f"Person.{name}: expected shape {want}, got {np.shape(getattr(self, name))}")

    def observed(self) -> tuple[np.ndarray, np.ndarray]:
        """(J, 2) pixels and (J, 3) mm as observed, before any smoothing."""
        return (self.keypoints_2d if self.observed_2d is None else self.observed_2d,
                self.keypoints_3d if self.observed_3d is None else self.observed_3d)

    def seen(self, image_size: tuple[int, int] | None) -> np.ndarray:
        """(J,) bool: the joints the pose model saw, as the pose files and the drawings say: a
        confidence of MIN_CONFIDENCE or more and, where `image_size` (width, height) is given, the
        2D keypoint on that image; the hips (the root) only with a knee seen too (HIP_ROLES).
        The others (off the picture, hidden, invented) are guesses."""
        seen = np.asarray(self.confidence, dtype=float) >= MIN_CONFIDENCE
        if image_size is not None:
            (width, height), (u, v) = image_size, np.asarray(self.keypoints_2d, dtype=float).T
            seen &= (u >= 0) & (u < width) & (v >= 0) & (v < height)
        if not seen[self._joints_of(KNEE_ROLES)].any():
            seen[self._joints_of(HIP_ROLES)] = False
        return seen

    def _joints_of(self, roles: tuple[str, ...]) -> list[int]:
        """The indices of the joints that play these roles in the person's skeleton (Skeleton.roles)."""
        return [i for role in roles for i in self.skeleton.role(role)]

    @property
    def root(self) -> np.ndarray:
        """The root in mm: the pelvis of the 17 joints, the midpoint of the hips of the 33
        BlazePose landmarks (the same point), as `skeleton` says."""
        if len(self.skeleton.joints) != len(self.confidence):
            raise ValueError(f"Person.root: the person has {len(self.confidence)} joints, its skeleton "
                             f"{self.skeleton.name} {len(self.skeleton.joints)}; give Person(..., skeleton=...)")
        return self.skeleton.root_point(self.keypoints_3d)


@dataclass
class Dropped:
    """A person seen but not reported, and the stage that left them out."""

    stage: str                  # "max_people" (detector: over the cap), "presence" (pose model: below
                                # min_presence), "neighbour" (the pose lies on another person), "duplicate",
                                # "unconfirmed" (a video's track not confirmed: a false start)
    score: float                # the detector's score (max_people) or the pose model's presence
    bbox: np.ndarray            # (4,) x0, y0, x1, y1 in pixels


@dataclass
class Frame:
    index: int
    time: float                 # seconds from the start of the input
    people: list[Person] = field(default_factory=list)
    # the people seen but dropped, each with its stage; empty with no people means the
    # detector found nobody
    dropped: list[Dropped] = field(default_factory=list)


@dataclass
class Track:
    """One person's track as batched arrays, from the first frame of the recording that holds the
    person to the last (F rows, `rows` into Recording.frames): NaN keypoints and zero confidence
    where the person is absent (`present`), the keypoints as observed beside them (`Person.observed`)."""

    id: int
    rows: np.ndarray            # (F,) indices into Recording.frames
    present: np.ndarray         # (F,) bool
    people: list[Person | None]  # (F,) the person in each row (None: absent)
    keypoints_2d: np.ndarray    # (F, J, 2) px
    keypoints_3d: np.ndarray    # (F, J, 3) mm
    confidence: np.ndarray      # (F, J)
    observed_2d: np.ndarray     # (F, J, 2) px, before any smoothing
    observed_3d: np.ndarray     # (F, J, 3) mm, before any smoothing

    @classmethod
    def of(cls, rec: Recording, person_id: int) -> Track:
        """The track of `person_id` in `rec` (ValueError when nobody has that id)."""
        held = [(i, p) for i, f in enumerate(rec.frames) for p in f.people if p.id == person_id]
        if not held:
            raise ValueError(f"no person with id {person_id} in {rec.source}")
        rows = np.arange(held[0][0], held[-1][0] + 1)
        people: list[Person | None] = [None] * len(rows)
        for i, p in held:
            people[i - rows[0]] = p
        j = len(rec.joints)
        out = {name: np.full((len(rows), j, d), np.nan) for name, d in
               (("keypoints_2d", 2), ("keypoints_3d", 3), ("observed_2d", 2), ("observed_3d", 3))}
        conf = np.zeros((len(rows), j))
        for r, p in enumerate(people):
            if p is not None:
                out["keypoints_2d"][r], out["keypoints_3d"][r], conf[r] = p.keypoints_2d, p.keypoints_3d, p.confidence
                out["observed_2d"][r], out["observed_3d"][r] = p.observed()
        return cls(person_id, rows, np.array([p is not None for p in people]), people, confidence=conf, **out)


@dataclass
class Recording:
    """Everything posecam found in one input: an image, a video, or the fusion of several views."""

    source: str
    width: int
    height: int
    intrinsics: Intrinsics | None
    joints: tuple[str, ...]
    frames: list[Frame] = field(default_factory=list)
    model: str = ""
    fps: float | None = None
    frame_of_reference: str = "camera"   # "camera", "reference camera NAME" or "world"
    floor: Floor | None = None           # the ground plane under the people (posecam.scale.metric), camera frame
    cameras: list[dict] = field(default_factory=list)   # fused: what fusion says of each input camera

    @property
    def view_size(self) -> tuple[int, int] | None:
        """(width, height) of the one image its people's joints were seen in (Person.seen); None
        for fused poses, whose joints several cameras saw (one off the reference camera's image
        may be in another's)."""
        return (self.width, self.height) if self.frame_of_reference == "camera" else None

    @property
    def person_ids(self) -> list[int]:
        """Every track's id, in order."""
        return sorted({p.id for f in self.frames for p in f.people})

    def tracks(self) -> list[Track]:
        """Every person's track as batched arrays (`Track`), by id."""
        return [Track.of(self, pid) for pid in self.person_ids]

    @property
    def root_joint(self) -> str:
        """What `Person.root` is: "pelvis" (17 joints), "mid_hip" (33 landmarks: the hips' midpoint)."""
        return skeleton_of(self.joints).root
