"""One rig for a session (posecam.multiview.session, `posecam calibrate`): synthetic takes of one
known rig (tests/synth_rig.py, world z up on the floor), each take a different walk of its own
person; the real takes are in tests/test_demo_session.py."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from conftest import run_posecam
from posecam import FuseOptions, calibrate_session, fuse_recordings
from posecam.errors import FusionError, InputError
from posecam.geometry.camera import Rig
from posecam.io.calibration import read_calibration
from posecam.io.poses import write_poses
from posecam.multiview.fuse import floor_rig
from posecam.multiview.session import disagreeing
from posecam.multiview.world import floor_world
from posecam.views import session_takes
from synth_rig import make_rig, monocular_views, relative_rotation_error_deg, skeleton_motion

RIG = sorted(make_rig(), key=lambda c: c.name)     # in the order `posecam calibrate` reads their files


def standing(n: int, seed: int, centre=(0.0, 0.0)) -> np.ndarray:
    """(F, 17, 3) a person walking a loop upright: synth_rig's walker, trunk unbent, legs kept
    straight and swung from the hips (its lower foot 40-100 mm over the floor), arms swinging."""
    world = skeleton_motion(n, seed=seed, centre=centre, lean=0.0)
    swing = 0.3 * np.sin(np.arange(n) / 30.0 * 2 * np.pi * 0.9 + seed)
    for hip, knee, ankle, side in ((1, 2, 3, 1.0), (4, 5, 6, -1.0)):
        leg = np.stack([np.zeros(n), side * np.sin(swing), -np.cos(swing)], axis=-1)
        world[:, knee] = world[:, hip] + 440 * leg
        world[:, ankle] = world[:, hip] + 870 * leg
    return world


def take(n: int, seed: int, centre=(0.0, 0.0), offsets=None, **kw) -> list:
    return monocular_views(RIG, standing(n, seed, centre), seed=seed + 10, offsets=offsets, **kw)


@pytest.fixture(scope="module")
def takes() -> dict[str, list]:
    """Two takes of the rig: a long walk about the middle, a shorter one off to a side, started by hand."""
    return {"walk": take(90, 0, offsets=[0, 2, -1, 0]), "side": take(60, 3, centre=(600.0, -400.0))}


@pytest.fixture(scope="module")
def session(takes):
    return calibrate_session(takes)


def world_errors(rig: Rig) -> tuple[float, dict[str, float]]:
    """The rig's vertical against the synthetic world's z (deg; the rigs aligned by their
    cameras' rotations) and each camera's height error (mm) at the synthetic rig's scale."""
    truth = {c.name: c for c in RIG}
    qs = [truth[c.name].rotation.T @ c.rotation for c in rig.cameras]
    u, _, vt = np.linalg.svd(sum(qs))
    q = u @ np.diag([1, 1, np.linalg.det(u @ vt)]) @ vt
    vertical = float(np.degrees(np.arccos(np.clip((q @ [0, 0, 1.0])[2], -1, 1))))
    ours = np.array([c.centre for c in rig.cameras])
    true = np.array([truth[c.name].centre for c in rig.cameras])
    scale = np.linalg.norm(true[:, :2] - true[:, :2].mean(0)) / np.linalg.norm(ours[:, :2] - ours[:, :2].mean(0))
    return vertical, {c.name: float(ours[i, 2] * scale - true[i, 2]) for i, c in enumerate(rig.cameras)}


def test_the_session_rig_matches_the_cameras_and_stands_on_the_floor(session):
    """Every camera kept; each pair's rotation within 1.5 deg of the truth; the rig's world has
    its Z up (within 3 deg of the truth's) and its cameras at their heights above the floor
    (within 150 mm, the synthetic ankle's own height varying by 120 mm)."""
    assert session.rig.names == [c.name for c in RIG] and session.rig.reference is None, session.warnings
    truth = {c.name: c for c in RIG}
    for a in session.rig.cameras[1:]:
        b = session.rig.cameras[0]
        err = relative_rotation_error_deg(b.rotation, a.rotation, truth[b.name].rotation, truth[a.name].rotation)
        assert err < 1.5, (a.name, err)
    vertical, heights = world_errors(session.rig)
    assert vertical < 3.0, vertical
    assert all(abs(h) < 150 for h in heights.values()), heights
    assert "floor" in session.world


def test_each_take_keeps_its_own_offsets_and_fuses_through_the_rig(takes, session):
    """The walk's cameras started 2 and -1 frames apart are found so (within half a frame), the
    side take's at 0; fusing a take through the written rig finds them again (the rig says its
    cameras do not record in step) and writes its poses in the floor's world."""
    walk, side = session.takes
    assert walk.name == "walk" and np.allclose(walk.offsets, [0, 2, -1, 0], atol=0.5), walk.offsets
    assert np.allclose(side.offsets, 0, atol=0.5), side.offsets
    assert all(np.isfinite(walk.reprojection_px)) and max(walk.reprojection_px) < 10, walk.reprojection_px
    assert not session.rig.synchronised
    fused = fuse_recordings(takes["walk"], FuseOptions(calibration=session.rig))
    assert np.allclose(fused.offsets, [0, 2, -1, 0], atol=0.5), fused.offsets
    assert fused.recording.frame_of_reference == "world"
    feet = np.array([p.keypoints_3d[[3, 6], 2].min() for f in fused.recording.frames for p in f.people])
    assert 0 < np.median(feet) < 250, np.median(feet)            # ankles just above the floor (z up, mm)


def test_a_camera_misnamed_in_one_take_is_named_and_left_out(takes):
    """right and left (both 1080x1920) exchanged in the shorter take: a warning names that take
    and both cameras, they are left out of it, and the rig stays the truth's."""
    swap = {"right": "left", "left": "right"}
    side = [replace(r, source=swap.get(r.source, r.source)) for r in takes["side"]]
    result = calibrate_session({"walk": takes["walk"], "side": side})
    lines = [w for w in result.warnings if "does not fit the session" in w]
    assert len(lines) == 2 and all("take side" in w for w in lines), result.warnings
    assert sorted(result.takes[1].left_out) == ["left", "right"]
    truth = {c.name: c for c in RIG}
    b = result.rig.cameras[0]
    for a in result.rig.cameras[1:]:
        err = relative_rotation_error_deg(b.rotation, a.rotation, truth[b.name].rotation, truth[a.name].rotation)
        assert err < 1.5, (a.name, err)


def test_own_rigs_that_place_a_camera_differently_disagree_on_it():
    """A camera turned by 20 deg in one rig is named; the rig's other cameras are not, and a
    rig against itself, moved and scaled as a whole, disagrees on nothing."""
    import cv2

    moved = Rig([replace(c, translation=2.0 * (c.translation + c.rotation @ [300.0, 0, 0])) for c in RIG])
    assert disagreeing(Rig(RIG), moved) == {}
    turn = cv2.Rodrigues(np.array([0.0, np.radians(20), 0.0]))[0]
    turned = Rig([replace(c, rotation=turn @ c.rotation) if c.name == "right" else c for c in RIG])
    assert list(disagreeing(Rig(RIG), turned)) == ["right"]


def test_a_still_take_joins_the_session_and_alone_is_refused_with_what_helps(takes):
    """A static trial (one pose held: the views' joints move a few mm) is refused alone, naming
    posecam calibrate; in a session it is taken at offset 0, said so, and fused through its rig."""
    pose = standing(1, seed=5)
    still = monocular_views(RIG, np.repeat(pose, 40, axis=0), seed=6, joint_noise=5.0, depth_noise=5.0)
    with pytest.raises(FusionError, match=r"nobody moves in this take.*posecam calibrate"):
        fuse_recordings(still)
    result = calibrate_session({**takes, "static": still})
    assert result.takes[2].still and result.takes[2].offsets == [0.0] * 4
    assert any("take static: nobody moves" in w for w in result.warnings)
    fused = fuse_recordings(still, FuseOptions(calibration=result.rig))
    assert fused.offsets == [0.0] * 4 and any("nobody moves" in w for w in fused.warnings)
    assert sum(len(f.people) for f in fused.recording.frames) == 40


def test_a_camera_of_another_size_is_refused_by_name(takes):
    small = [replace(r, width=r.width // 2, height=r.height // 2) if r.source == "right" else r
             for r in takes["side"]]
    with pytest.raises(InputError, match="camera right films 1080x1920 in one take and 540x960 in take side"):
        calibrate_session({"walk": takes["walk"], "side": small})


def test_the_floor_world_from_people_in_a_camera_frame():
    """People triangulated in the first camera's frame: the world found has the truth's vertical
    (within 2 deg) and puts each camera at its height above the floor (within 100 mm), the
    origin under the people."""
    ref = RIG[0]
    in_ref = Rig([replace(c, rotation=c.rotation @ ref.rotation.T,
                          translation=c.translation - c.rotation @ ref.rotation.T @ ref.translation) for c in RIG],
                 ref.name)
    poses = ref.to_camera(standing(150, seed=1))
    world = floor_world(in_ref, poses, np.ones(poses.shape[:2]), tuple(take(1, 0)[0].joints))
    assert not isinstance(world, str), world
    rig = world.rig(in_ref)
    vertical, heights = world_errors(rig)
    assert vertical < 2.0 and all(abs(h) < 100 for h in heights.values()), (vertical, heights)
    assert np.linalg.norm(world.points(poses[:, 0]).mean(axis=0)[:2]) < 1000
    assert isinstance(floor_world(in_ref, poses[:5], np.ones((5, 17)), tuple(take(1, 0)[0].joints)), str)


def test_fuse_save_calibration_writes_the_floor_world(takes):
    """`fuse --save-calibration`'s rig (floor_rig): an estimated rig moved onto the floor, its
    vertical the truth's within 3 deg; a given calibration kept as it is."""
    result = fuse_recordings(takes["walk"])
    rig, frame, lines = floor_rig(result)
    assert rig.reference is None and "floor" in frame and not lines
    assert world_errors(rig)[0] < 3.0
    given = fuse_recordings(takes["walk"], FuseOptions(calibration=Rig(RIG), offsets=[0, 2, -1, 0]))
    assert floor_rig(given)[0] is given.rig


def write_take(folder: Path, recs: list) -> list[Path]:
    folder.mkdir(parents=True)
    paths = []
    for rec in recs:
        paths.append(folder / f"{rec.source}.json")
        write_poses(paths[-1], [rec])
    return paths


def test_session_folders_are_read_as_pose2sim_lays_them_out(tmp_path):
    """A take folder, a trial with its videos/ inside, a session folder of trials (its
    calibration/ left aside); a folder of nothing is refused by name, so are two takes of one name."""
    for trial in ("Trial_1", "Trial_2"):
        (tmp_path / "session" / trial / "videos").mkdir(parents=True)
        for n in ("cam01", "cam02"):
            (tmp_path / "session" / trial / "videos" / f"{n}.mp4").write_bytes(b"")
    (tmp_path / "session" / "calibration").mkdir()
    (tmp_path / "session" / "calibration" / "Calib.toml").write_text("")
    found = session_takes([str(tmp_path / "session")])
    assert list(found) == ["Trial_1", "Trial_2"] and all(len(v) == 2 for v in found.values())
    assert list(session_takes([str(tmp_path / "session" / "Trial_2")])) == ["Trial_2"]
    with pytest.raises(InputError, match="holds no take"):
        session_takes([str(tmp_path / "session" / "calibration")])
    with pytest.raises(InputError, match="two takes are named Trial_1"):
        session_takes([str(tmp_path / "session"), str(tmp_path / "session" / "Trial_1")])


@pytest.mark.slow
def test_posecam_calibrate_writes_a_rig_that_fuse_reads_in_step(tmp_path, takes, session):
    """The command gives the API's rig (to the pose files' rounding), in metres with Z up, marked
    unsynchronised; `posecam fuse` through it finds the take's offsets unasked and writes world
    poses, a session folder with --out-dir one file per take; bad input is one line."""
    for name, recs in takes.items():
        write_take(tmp_path / "session" / name, recs)
    r = run_posecam("calibrate", tmp_path / "session" / "walk", tmp_path / "session" / "side", "-o",
                    tmp_path / "rig.toml")
    assert r.returncode == 0, r.stderr
    assert "take" in r.stdout and "walk" in r.stdout and "wrote" in r.stdout
    rig = read_calibration(tmp_path / "rig.toml")
    assert not rig.synchronised and "floor" in (tmp_path / "rig.toml").read_text()
    for a, b in zip(rig.cameras, session.rig.cameras):     # the API on the same takes, before the files' rounding
        assert relative_rotation_error_deg(np.eye(3), a.rotation, np.eye(3), b.rotation) < 0.05
        assert np.linalg.norm(a.centre - b.centre) < 20
    assert min(c.centre[2] for c in rig.cameras) > 0
    r = run_posecam("fuse", *sorted((tmp_path / "session" / "walk").iterdir()), "--calibration", tmp_path / "rig.toml",
                    "-o", tmp_path / "walk.json")
    assert r.returncode == 0 and "offset 0" not in r.stderr, r.stderr
    doc = json.loads((tmp_path / "walk.json").read_text())["inputs"][0]
    assert doc["frame"] == "world" and [c["offset"] for c in doc["cameras"]] == pytest.approx([0, 2, -1, 0], abs=0.5)
    (tmp_path / "out").mkdir()
    r = run_posecam("fuse", tmp_path / "session", "--calibration", tmp_path / "rig.toml", "--out-dir", tmp_path / "out")
    assert r.returncode == 0 and "2 written, 0 skipped" in r.stderr, r.stderr      # the session folder's takes
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["side.json", "walk.json"]
    r = run_posecam("calibrate", tmp_path / "nothing", "-o", tmp_path / "x.toml")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "is not one" in r.stderr
    r = run_posecam("calibrate", tmp_path / "session" / "walk", "-o", tmp_path / "x.json")
    assert r.returncode == 2 and "-o must end in .toml" in r.stderr and not (tmp_path / "x.json").exists()
