"""`fuse --viz`: the fused poses projected into every view, one named still or a video of
every frame; on the real clip's own frames and on synthetic views whose videos do not exist."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from conftest import DATA, run_posecam
from posecam.viz.fusion_grid import TILE_SIDE


def _synthetic_views(tmp_path, n_frames=25):
    from synth_rig import write_take

    return write_take(tmp_path, n_frames)


@pytest.mark.slow
def test_fused_video_has_every_frame_and_names_it(tmp_path):
    cams, paths, calib = _synthetic_views(tmp_path)
    video, still, out = tmp_path / "grid.mp4", tmp_path / "grid.png", tmp_path / "fused.json"
    run = run_posecam("fuse", *paths, "--calibration", calib, "--start", "5", "-o", out, "--viz", video)
    assert run.returncode == 0, run.stderr
    frames = json.loads(out.read_text())["inputs"][0]["frames"]
    cap = cv2.VideoCapture(str(video))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == len(frames) == 20
    ok, first = cap.read()
    # landscape and portrait views: square cells of TILE_SIDE, two to a row
    assert ok and len(cams) == 4 and first.shape[:2] == (2 * TILE_SIDE, 2 * TILE_SIDE)
    # black tiles (the synthetic views have no video) with the skeletons drawn in every view
    for v in range(len(cams)):
        row, col = divmod(v, 2)
        tile = first[row * TILE_SIDE + 60:(row + 1) * TILE_SIDE, col * TILE_SIDE:(col + 1) * TILE_SIDE]
        assert (tile.max(axis=2) > 100).sum() > 200, v
    run = run_posecam("fuse", *paths, "--calibration", calib, "--start", "5", "--viz", still)
    assert run.returncode == 0, run.stderr
    picture = cv2.imread(str(still))
    label = picture[5:45, 5:300].astype(int)
    assert (label.min(axis=2) > 200).sum() > 100     # "frame N  T s", white on the black tile
    # the still is one of the video's frames, and its label is that frame's, not its neighbours'
    cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
    video_frames = [cap.read()[1].astype(int) for _ in frames]
    k = int(np.argmin([np.abs(f - picture).mean() for f in video_frames]))
    assert np.abs(video_frames[k] - picture).mean() < 3.0 and 4 < k < 16    # a middle frame
    same = np.abs(video_frames[k][5:45, 5:300] - label).mean()
    neighbour = np.abs(video_frames[k + 1][5:45, 5:300] - label).mean()     # "frame k+1": other digits
    assert same < 2.0 < neighbour, (same, neighbour)


def test_viz3d_video_draws_every_frame_of_the_3d_view(tmp_path):
    """--viz3d FILE.mp4 on a real clip: a frame per frame, the person in the page's colour, and
    the skeleton's place on the picture follows the person walking to the right (synthetic)."""
    from posecam.results import Frame, Person, Recording
    from posecam.skeleton import H36M_JOINTS
    from posecam.viz.render3d import render_frames
    from posecam.viz.view3d import PALETTE

    video = tmp_path / "view.mp4"
    run = run_posecam("predict", DATA / "balance_cam01_30f.mp4", "--viz3d", video)
    assert run.returncode == 0, run.stderr
    cap = cv2.VideoCapture(str(video))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 30 and int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)) == 960
    ok, bgr = cap.read()
    orange = np.abs(bgr.astype(int) - PALETTE[0][::-1]).sum(axis=2) < 60
    assert ok and orange.sum() > 300

    rng = np.random.default_rng(0)
    pose = rng.normal(0, 150, (17, 3)) + [0, 0, 3000]
    frames = [Frame(i, i / 30, [Person(0, 1.0, np.zeros(4), np.zeros((17, 2)), pose + [100.0 * i, 0, 0], np.ones(17))])
              for i in range(10)]
    rec = Recording("walk", 640, 480, None, H36M_JOINTS, frames, fps=30.0)
    xs = []
    for image in render_frames(rec):
        mask = np.abs(image.astype(int) - PALETTE[0]).sum(axis=2) < 60
        xs.append(np.nonzero(mask)[1].mean())
    assert np.all(np.diff(xs) > 0), xs


def test_predict_viz_draws_every_photo_of_a_folder(tmp_path):
    photos, drawn = tmp_path / "photos", tmp_path / "drawn"
    photos.mkdir(), drawn.mkdir()
    for name in ("messi5.jpg", "basketball2.png", "fruits.jpg"):
        (photos / name).write_bytes((DATA / name).read_bytes())
    run = run_posecam("predict", photos, "--viz", f"{drawn}/", "-o", tmp_path / "poses.json")
    assert run.returncode == 0, run.stderr
    assert sorted(p.name for p in drawn.iterdir()) == ["basketball2_pose.png", "fruits_pose.jpg", "messi5_pose.jpg"]
    for name, picture in (("messi5.jpg", "messi5_pose.jpg"), ("basketball2.png", "basketball2_pose.png")):
        source, out = cv2.imread(str(photos / name)), cv2.imread(str(drawn / picture))
        assert out.shape == source.shape
        assert (np.abs(out.astype(int) - source).max(axis=2) > 60).sum() > 500, name   # skeletons drawn
    run = run_posecam("predict", photos, DATA / "balance_cam01_30f.mp4", "--viz", drawn)
    assert run.returncode == 2 and "--viz DIR draws photos" in run.stderr
    run = run_posecam("predict", photos, "--viz", tmp_path / "missing")
    assert run.returncode == 4 and "does not exist" in run.stderr


def test_joints_a_view_cannot_see_are_not_drawn():
    """A fused joint that is missing (NaN) or behind a camera is left out of that camera's tile
    (OpenCV cannot draw them), and a person wholly behind it is not drawn at all."""
    from synth_rig import make_rig, skeleton_motion

    from posecam.results import Frame, Person, Recording
    from posecam.skeleton import H36M_JOINTS
    from posecam.viz.fusion_grid import _in_view, _tile

    cam = make_rig()[0]
    xyz = skeleton_motion(1)[0]
    xyz[3] = np.nan
    xyz[6] = cam.centre - 500.0 * cam.rotation[2]          # half a metre behind the camera
    person = Person(0, 1.0, np.zeros(4), np.zeros((17, 2)), xyz, np.ones(17))
    seen = _in_view(cam, person)
    assert seen.confidence[3] == 0 and seen.confidence[6] == 0 and seen.confidence[0] == 1
    assert np.isfinite(seen.keypoints_2d).all() and np.isfinite(seen.bbox).all()
    behind = Person(1, 1.0, np.zeros(4), np.zeros((17, 2)), np.tile(xyz[6], (17, 1)), np.ones(17))
    assert _in_view(cam, behind) is None
    rec = Recording("v", cam.size[0], cam.size[1], cam.intrinsics, H36M_JOINTS)
    tile = _tile(cam, rec, Frame(0, 0.0, [person, behind]), np.zeros((cam.size[1], cam.size[0], 3), np.uint8))
    assert max(tile.shape[:2]) == TILE_SIDE and tile.max() > 0


def test_each_view_is_large_and_its_labels_readable():
    """Four portrait views (Pose2Sim's 1088x1920 cameras) make one row of 405x720 tiles, and
    each person's label is drawn at the tile's size: its letters at least 10 px high (drawn at
    full size and shrunk with the view, they were 6 px in a 480 px high tile)."""
    from synth_rig import CameraSpec, make_rig, skeleton_motion

    from posecam.results import Frame, Person, Recording
    from posecam.skeleton import H36M_JOINTS
    from posecam.viz.draw import draw_people
    from posecam.viz.fusion_grid import _grid, _tile

    cams = make_rig([CameraSpec(f"cam{i}", (1088, 1920), 1400.0, 90.0 * i, 3500.0, 1200.0) for i in range(4)])
    person = Person(0, 1.0, np.zeros(4), np.zeros((17, 2)), skeleton_motion(1)[0], np.ones(17))
    rec = Recording("v", 1088, 1920, cams[0].intrinsics, H36M_JOINTS)
    black = np.zeros((1920, 1088, 3), np.uint8)
    tiles = [_tile(cam, rec, Frame(0, 0.0, [person]), black) for cam in cams]
    assert all(t.shape == (TILE_SIDE, round(1088 * TILE_SIDE / 1920), 3) for t in tiles)
    mosaic = _grid(tiles, Frame(0, 0.0, [person]))
    assert mosaic.shape[:2] == (TILE_SIDE, 4 * tiles[0].shape[1])
    label = np.argwhere((tiles[0][..., 0] > 200) & (tiles[0][..., 1] > 200) & (tiles[0][..., 2] < 60))  # yellow
    assert len(label) and np.ptp(label[:, 0]) + 1 >= 10, np.ptp(label[:, 0]) + 1
    # the yardstick: the same label drawn on the full-size view, then shrunk as the old mosaic did
    from posecam.viz.fusion_grid import _in_view

    full = cv2.resize(draw_people(black, [_in_view(cams[0], person)], H36M_JOINTS), (272, 480))
    old = np.argwhere((full[..., 0] > 150) & (full[..., 1] > 150) & (full[..., 2] < 90))
    assert np.ptp(old[:, 0]) + 1 < np.ptp(label[:, 0]) + 1
