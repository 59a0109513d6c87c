"""The figures fusion reports per camera: the reprojection error and joints used count only the
joints two views or more see, and a person one camera alone sees is written with views 1.
The reference figures are computed here with cv2.projectPoints, from the fused recording and
the views' own keypoints, not with posecam's projection."""

import json

import cv2
import numpy as np

from posecam.geometry.camera import Rig
from posecam.io.poses import read_poses, write_poses
from posecam.multiview.fuse import fuse_recordings
from posecam.multiview.options import FuseOptions
from posecam.skeleton import MIN_CONFIDENCE
from synth_rig import make_rig, monocular_views, skeleton_motion

N = 40


def _take():
    """Two people: one every camera sees, and a bystander only the first camera ("front") sees."""
    cams = make_rig()
    world = np.stack([skeleton_motion(N, seed=0), skeleton_motion(N, seed=3, centre=(1500.0, -1600.0))])
    visible = np.ones((2, len(cams), N), bool)
    visible[1, 1:] = False
    recs = monocular_views(cams, world, visible=visible, outlier_rate=0.0)
    return cams, world, recs


def _project(cam, pts: np.ndarray) -> np.ndarray:
    rvec = cv2.Rodrigues(np.asarray(cam.rotation, np.float64))[0]
    uv, _ = cv2.projectPoints(np.ascontiguousarray(pts, np.float64), rvec, np.asarray(cam.translation, np.float64),
                              cam.intrinsics.matrix, np.asarray(cam.distortion, np.float64))
    return uv.reshape(-1, 2)


def _nearest(cam, pts: np.ndarray, people: list) -> tuple[object, np.ndarray] | None:
    """The view's person nearest the projection of `pts` (median pixel distance), and the distances."""
    proj = _project(cam, pts)
    best = None
    for q in people:
        d = np.linalg.norm(q.keypoints_2d - proj, axis=1)
        if best is None or np.median(d) < np.median(best[1]):
            best = (q, d)
    return best if best is not None and np.median(best[1]) < 80 else None


def _independent(cams, recs, fused) -> tuple[list[float], list[int], list[float]]:
    """Per camera: the median pixel error of the fused joints two views or more see (and their
    count), and the median over every fused joint it sees (what the report said before)."""
    shared_err, all_err = [[] for _ in cams], [[] for _ in cams]
    for i, frame in enumerate(fused.frames):
        for p in frame.people:
            seen, dist = np.zeros((len(cams), len(p.confidence)), bool), np.zeros((len(cams), len(p.confidence)))
            for v, (cam, rec) in enumerate(zip(cams, recs)):
                got = _nearest(cam, p.keypoints_3d, rec.frames[i].people)
                if got is not None:
                    seen[v], dist[v] = got[0].confidence >= MIN_CONFIDENCE, got[1]
            shared = seen.sum(axis=0) >= 2
            for v in range(len(cams)):
                shared_err[v].append(dist[v][seen[v] & shared])
                all_err[v].append(dist[v][seen[v]])
    flat = [np.concatenate(e) for e in shared_err]
    return ([float(np.median(e)) for e in flat], [len(e) for e in flat],
            [float(np.median(np.concatenate(e))) for e in all_err])


def test_a_person_one_camera_sees_has_views_1_and_stays_out_of_the_figures(tmp_path):
    """The report is of the fused poses as fused, before they are smoothed over time (smooth=False)."""
    cams, world, recs = _take()
    result = fuse_recordings(recs, FuseOptions(calibration=Rig(cams), smooth=False))
    fused = result.recording
    views = {}
    for i, frame in enumerate(fused.frames):
        for p in frame.people:
            d = np.median(np.linalg.norm(world[:, i] - p.keypoints_3d, axis=-1), axis=1)
            views.setdefault(int(np.argmin(d)), []).append(p.views)
    assert set(views) == {0, 1}, views
    assert views[1] == [1] * N, views[1]                        # the bystander: one camera's pose
    assert min(views[0]) >= 2 and np.median(views[0]) == len(cams), views[0]
    # the file says so too, and reads back
    path = tmp_path / "fused.json"
    write_poses(path, [fused])
    doc = json.loads(path.read_text())
    assert sorted({p["views"] for f in doc["inputs"][0]["frames"] for p in f["people"]}) == sorted(
        {v for vs in views.values() for v in vs})
    back = read_poses(path)[0]
    assert [[p.views for p in f.people] for f in back.frames] == [[p.views for p in f.people] for f in fused.frames]

    shared, counts, everyone = _independent(cams, recs, fused)
    report = {c.name: c for c in result.cameras}
    front = report["front"]
    # the bystander reprojects onto his own keypoints: counted, he would pull front's median down
    assert everyone[0] < 0.7 * shared[0], (everyone, shared)
    for cam, px, k in zip(cams, shared, counts):
        assert np.isclose(report[cam.name].reprojection_px, px, rtol=1e-6), (cam.name, report[cam.name], px)
        assert report[cam.name].joints_used == k, (cam.name, report[cam.name].joints_used, k)
    assert front.joints_used < sum(len(f.people) for f in recs[0].frames) * len(recs[0].joints)


def test_reported_error_matches_a_projection_on_a_noisy_rig():
    """One person every camera sees, 3 px of pixel noise, triangulated: the report equals the
    independent projection of the fused joints two views or more see confidently."""
    cams = make_rig()
    world = skeleton_motion(N, seed=5)
    recs = monocular_views(cams, world, pixel_noise=3.0, outlier_rate=0.0)
    result = fuse_recordings(recs, FuseOptions(calibration=Rig(cams), method="triangulate", smooth=False))
    assert all(p.views == len(cams) for f in result.recording.frames for p in f.people)
    shared, counts, _ = _independent(cams, recs, result.recording)
    for cam, px, k in zip(cams, shared, counts):
        rep = next(c for c in result.cameras if c.name == cam.name)
        assert np.isclose(rep.reprojection_px, px, rtol=1e-6) and rep.joints_used == k, (cam.name, rep, px, k)
        assert 0.5 < px < 10, px                    # 3 px of noise, triangulated: a few px


def test_a_pose_file_with_a_bad_views_count_is_refused_naming_it(tmp_path):
    import pytest

    from posecam.errors import InputError

    _, _, recs = _take()
    path = tmp_path / "front.json"
    write_poses(path, [recs[0]])
    doc = json.loads(path.read_text())
    assert "views" not in doc["inputs"][0]["frames"][0]["people"][0]      # a monocular pose: not written
    assert read_poses(path)[0].frames[0].people[0].views == 0
    for bad in (-1, 1.5, "2", True):
        doc["inputs"][0]["frames"][0]["people"][0]["views"] = bad
        path.write_text(json.dumps(doc))
        with pytest.raises(InputError, match=r"people\[0\]: views: must be a whole number"):
            read_poses(path)
