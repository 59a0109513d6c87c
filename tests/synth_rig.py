"""Synthetic multi-camera recordings: a walking, waving 17-joint skeleton seen by known cameras.

Each view's monocular poses are made the way `posecam predict` makes them: 2D keypoints
with pixel noise, a metric root-relative pose with tens of mm of noise, placed by solving the
root translation with the *default* intrinsics (not the true ones), plus per-frame root-depth
noise. World frame: z up, mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from posecam.geometry.camera import Intrinsics
from posecam.geometry.lift import solve_root_translation
from posecam.geometry.camera import CameraCalibration
from posecam.results import Frame, Person, Recording
from posecam.skeleton import H36M_JOINTS


def _rot(axis: str, angle: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations about a world axis."""
    c, s = np.cos(angle), np.sin(angle)
    o, i = np.zeros_like(angle), np.ones_like(angle)
    m = {"x": [[i, o, o], [o, c, -s], [o, s, c]],
         "y": [[c, o, s], [o, i, o], [-s, o, c]],
         "z": [[c, -s, o], [s, c, o], [o, o, i]]}[axis]
    return np.moveaxis(np.array(m), (0, 1), (-2, -1))


def skeleton_motion(n_frames: int, seed: int = 0, centre=(0.0, 0.0), walk=(0.0, 0.0), start: float = 0.0,
                    lean: float = 0.15) -> np.ndarray:
    """(F, 17, 3) world joints (mm, z up) of a person walking a loop, swinging arms and legs,
    turning, bending and now and then raising an arm sideways; `walk` (mm/s) moves the loop
    across the scene (people whose paths cross); `start` (frames, may be fractional) shifts
    the motion in time: frame i shows the instant i + start; `lean` (rad): how far the trunk
    bends forward and back."""
    rng = np.random.default_rng(seed)
    t = (np.arange(n_frames) + start) / 30.0
    phase = 2 * np.pi * 0.9 * t + rng.uniform(0, 2 * np.pi)
    yaw = 0.6 * t + rng.uniform(0, 2 * np.pi)                      # slowly turning body
    root = np.stack([centre[0] + walk[0] * t + 700 * np.cos(0.35 * t), centre[1] + walk[1] * t + 500 * np.sin(0.5 * t),
                     950 + 30 * np.sin(2 * phase)], axis=-1)
    lean = lean * np.sin(0.7 * t)                                   # bending forward and back

    def limb(start, swing, side, bend, lengths):
        """Two segments hanging from `start`, swung about x (forward) and y (sideways)."""
        r1 = _rot("x", swing) @ _rot("y", side)
        a = start + np.einsum("fij,j->fi", r1, [0, 0, -lengths[0]])
        r2 = r1 @ _rot("x", bend)
        b = a + np.einsum("fij,j->fi", r2, [0, 0, -lengths[1]])
        return a, b

    zero = np.zeros(n_frames)
    o = zero[:, None] * np.zeros(3)
    up = _rot("x", -lean)
    pelvis = o.copy()
    spine = np.einsum("fij,j->fi", up, [0, 0, 230])
    thorax = np.einsum("fij,j->fi", up, [0, 0, 480])
    neck_dir = np.einsum("fij,j->fi", up, [0, 0, 1])
    nose = thorax + 160 * neck_dir + np.array([0, 90, 0])
    head = thorax + 250 * neck_dir
    r_hip, l_hip = o + [-110, 0, 0], o + [110, 0, 0]
    swing = 0.45 * np.sin(phase)
    r_knee, r_ankle = limb(r_hip, swing, zero, -0.5 * (1 + np.sin(phase + 1.2)), (440, 430))
    l_knee, l_ankle = limb(l_hip, -swing, zero, -0.5 * (1 + np.sin(phase + 1.2 + np.pi)), (440, 430))
    r_sh = thorax + np.einsum("fij,j->fi", up, [-170, 0, -20])
    l_sh = thorax + np.einsum("fij,j->fi", up, [170, 0, -20])
    raise_arm = 1.3 * np.clip(np.sin(0.8 * t), 0, None)           # abduction, to the side
    r_el, r_wr = limb(r_sh, -0.5 * swing, -0.2 - raise_arm, 0.4 + 0.3 * np.sin(phase), (290, 260))
    l_el, l_wr = limb(l_sh, 0.5 * swing, 0.2 + 0.5 * raise_arm, 0.4 - 0.3 * np.sin(phase), (290, 260))
    body = np.stack([pelvis, r_hip, r_knee, r_ankle, l_hip, l_knee, l_ankle, spine, thorax,
                     nose, head, l_sh, l_el, l_wr, r_sh, r_el, r_wr], axis=1)    # H36M order
    body = np.einsum("fij,fkj->fki", _rot("z", yaw), body)
    return body + root[:, None]


def look_at(centre: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World->camera R, t for a camera at `centre` looking at `target` (z up in the world)."""
    z = target - centre
    z = z / np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    r = np.stack([x, y, z])
    return r, -r @ centre


@dataclass
class CameraSpec:
    name: str
    size: tuple[int, int]
    focal: float
    azimuth_deg: float
    distance: float = 4000.0
    height: float = 1500.0


DEFAULT_SPECS = (
    CameraSpec("front", (1920, 1080), 1500.0, 0.0, 4200.0, 1600.0),
    CameraSpec("right", (1080, 1920), 1700.0, 80.0, 3800.0, 1200.0),
    CameraSpec("back", (1280, 720), 800.0, 175.0, 4600.0, 2100.0),
    CameraSpec("left", (1080, 1920), 1250.0, 260.0, 3500.0, 900.0),
)


def make_rig(specs=DEFAULT_SPECS, seed: int = 1, principal_noise: float = 0.01) -> list[CameraCalibration]:
    """Cameras looking at the scene centre; principal points off the image centre by about
    `principal_noise` image sizes."""
    rng = np.random.default_rng(seed)
    cams = []
    for s in specs:
        a = np.radians(s.azimuth_deg)
        centre = np.array([s.distance * np.cos(a), s.distance * np.sin(a), s.height])
        r, t = look_at(centre, np.array([0.0, 0.0, 1000.0]) + rng.normal(0, 150, 3))
        w, h = s.size
        k = Intrinsics(s.focal, s.focal * rng.uniform(0.99, 1.01),
                       w / 2 + rng.normal(0, 0.01 * w) * principal_noise / 0.01,
                       h / 2 + rng.normal(0, 0.01 * h) * principal_noise / 0.01)
        cams.append(CameraCalibration(s.name, s.size, k, r, t))
    return cams


def monocular_views(cams: list[CameraCalibration], world: np.ndarray, seed: int = 2,
                    pixel_noise: float = 2.0, joint_noise: float = 25.0, depth_noise: float = 50.0,
                    outlier_rate: float = 0.02, offsets: list[int] | None = None,
                    visible: np.ndarray | None = None, id_switch: dict | None = None,
                    known_lens: bool = False) -> list[Recording]:
    """What `posecam predict` would write for each camera, with default intrinsics (with
    `known_lens`, the cameras' own, as given by the user: source "flags").

    world: (F, J, 3) one person, or (P, F, J, 3) several. offsets[c] = o means camera c's frame
    i + o shows the instant of the world's frame i (its recording starts o frames earlier);
    frames that fall outside are dropped. visible (P, V, F) bool: who each camera detects when
    (default: everyone always). id_switch {(person, view): frame}: that view's tracker gives the
    person a new id (person + 10) from that frame on.
    """
    rng = np.random.default_rng(seed)
    world = world[None] if world.ndim == 3 else world
    n_people, n = world.shape[:2]
    if visible is None:
        visible = np.ones((n_people, len(cams), n), bool)
    recs = []
    for ci, cam in enumerate(cams):
        o = offsets[ci] if offsets else 0
        k = cam.intrinsics
        k0 = Intrinsics(k.fx, k.fy, k.cx, k.cy, "flags", k.distortion) if known_lens else Intrinsics.default(*cam.size)
        rec = Recording(cam.name, cam.size[0], cam.size[1], k0, H36M_JOINTS, model="synthetic", fps=30.0)
        for i in range(n + max(o, 0)):
            src = i - o
            people = []
            for p in range(n_people):
                if not 0 <= src < n or not visible[p, ci, src]:
                    continue
                switch = (id_switch or {}).get((p, ci))
                pid = p + 10 if switch is not None and src >= switch else p
                people.append(_observe(cam, world[p, src], pid, k0, rng, pixel_noise, joint_noise,
                                       depth_noise, outlier_rate))
            rec.frames.append(Frame(i, i / 30.0, people))
        recs.append(rec)
    return recs


def _observe(cam, joints, pid, k0, rng, pixel_noise, joint_noise, depth_noise, outlier_rate) -> Person:
    """One camera's monocular pose of one person in one frame."""
    pc = cam.to_camera(joints)
    uv = cam.project(joints) + rng.normal(0, pixel_noise, (len(pc), 2))
    conf = rng.uniform(0.55, 1.0, len(pc))
    low = rng.random(len(pc)) < 0.08
    conf[low] = rng.uniform(0.05, 0.45, low.sum())
    uv[low] += rng.normal(0, 40, (low.sum(), 2))          # unconfident joints are bad
    bad = rng.random(len(pc)) < outlier_rate
    uv[bad] += rng.normal(0, 60, (bad.sum(), 2))           # confident outliers
    rel = pc - pc[0] + rng.normal(0, joint_noise, pc.shape)
    t = solve_root_translation(rel, uv, conf, k0)
    t *= 1 + rng.normal(0, depth_noise) / t[2]             # per-frame root depth noise
    box = np.concatenate([uv.min(axis=0), uv.max(axis=0)])
    return Person(pid, 0.9, box, uv, rel + t, conf)


def relative_rotation_error_deg(r_est_a, r_est_b, r_true_a, r_true_b) -> float:
    """Angle between estimated and true rotation from camera a to camera b."""
    rel_est = r_est_b @ r_est_a.T
    rel_true = r_true_b @ r_true_a.T
    d = rel_est @ rel_true.T
    return float(np.degrees(np.linalg.norm(cv2.Rodrigues(d)[0])))


def write_qca(path, cams: list[CameraCalibration]) -> None:
    """A Qualisys .qca.txt holding these cameras (the inverse of posecam's reader)."""
    flip = np.diag([1.0, -1.0, -1.0])
    rows = []
    for c in cams:
        r = (flip @ c.rotation).ravel()                  # r11..r33, stored by column
        x, y, z = c.centre
        k, (w, h) = c.intrinsics, c.size
        rows.append(
            f'<camera active="1" avg-residual="0.4" model="none" serial="{c.name}" viewrotation="0">'
            f'<fov_video left="0" top="0" right="{w - 1}" bottom="{h - 1}"/>'
            f'<transform x="{x}" y="{y}" z="{z}" '
            + " ".join(f'r{i}{j}="{r[3 * (i - 1) + (j - 1)]}"' for i in (1, 2, 3) for j in (1, 2, 3))
            + "/>"
            f'<intrinsic focalLengthU="{k.fx * 64}" focalLengthV="{k.fy * 64}" centerPointU="{k.cx * 64}" '
            f'centerPointV="{k.cy * 64}" radialDistortion1="0" radialDistortion2="0" '
            f'tangentalDistortion1="0" tangentalDistortion2="0"/></camera>')
    with open(path, "w") as f:
        f.write("<?xml version='1.0'?>\n<qca><cameras>" + "".join(rows) + "</cameras></qca>\n")


def write_take(folder, n_frames: int) -> tuple[list[CameraCalibration], list, object]:
    """A synthetic take on disk: the default rig's views of `n_frames` of motion as posecam
    pose JSON files (one per camera) and the rig as calib.toml, all in `folder`."""
    from posecam.io.calibration import write_toml
    from posecam.io.poses import write_poses

    cams = make_rig()
    paths = []
    for rec in monocular_views(cams, skeleton_motion(n_frames)):
        paths.append(folder / f"{rec.source}.json")
        write_poses(paths[-1], [rec])
    write_toml(folder / "calib.toml", cams)
    return cams, paths, folder / "calib.toml"
