"""`posecam predict` and the PoseEstimator API on real photos and a real video clip."""

import csv
import json

import numpy as np

from conftest import DATA, EXAMPLES, run_posecam
from posecam import EstimatorOptions, PoseEstimator
from posecam.media import read_image
from posecam.skeleton import H36M_JOINTS, bone_lengths


def test_photo_gives_a_plausible_absolute_pose(tmp_path):
    out = tmp_path / "messi.json"
    r = run_posecam("predict", DATA / "messi5.jpg", "-o", out)
    assert r.returncode == 0, r.stderr
    doc = json.loads(out.read_text())
    assert doc["joints"] == list(H36M_JOINTS)
    inp = doc["inputs"][0]
    assert inp["intrinsics"]["source"] == "default"
    (person,) = inp["frames"][0]["people"]
    xyz = np.array(person["keypoints_3d"])
    assert xyz.shape == (17, 3) and 1000 < person["root"][2] < 10000
    bones = bone_lengths(xyz)
    for thigh in ("r_hip-r_knee", "l_hip-l_knee"):
        assert 300 < bones[thigh] < 600, bones
    for upper_arm in ("r_shoulder-r_elbow", "l_shoulder-l_elbow"):
        assert 200 < bones[upper_arm] < 400, bones
    conf = np.array(person["confidence"])
    assert ((0 <= conf) & (conf <= 1)).all() and conf.mean() > 0.5


def test_pose_projects_onto_its_2d_keypoints(estimator):
    frame = estimator.predict_image(read_image(EXAMPLES / "balance.jpg"))
    assert len(frame.people) == 2          # the man on the board, and a bystander at the left edge
    p = max(frame.people, key=lambda q: q.bbox[3] - q.bbox[1])
    from posecam.geometry.camera import Intrinsics, project

    ki = Intrinsics.default(1080, 1920)   # no intrinsics given: the default lens
    err = np.linalg.norm(project(p.keypoints_3d, ki) - p.keypoints_2d, axis=1)
    assert np.median(err) < 25  # the metric pose is placed on the image by the root translation


def test_intrinsics_change_the_depth_as_the_pinhole_model_says(estimator, tmp_path):
    img = read_image(EXAMPLES / "balance.jpg")
    from posecam.geometry.camera import Intrinsics

    near = estimator.predict_image(img, Intrinsics(1000, 1000, 540, 960)).people[0].root[2]
    far = estimator.predict_image(img, Intrinsics(2000, 2000, 540, 960)).people[0].root[2]
    assert 1.8 < far / near < 2.2


def test_lab_intrinsics_put_the_subject_where_the_lab_sees_him(tmp_path):
    out = tmp_path / "b.csv"
    r = run_posecam("predict", EXAMPLES / "balance.jpg", "--intrinsics", EXAMPLES / "cam01_intrinsics.json", "-o", out)
    assert r.returncode == 0, r.stderr
    rows = list(csv.reader(out.open()))
    assert rows[0] == "source,frame,person,joint,u,v,x,y,z,confidence,height,height_source,depth_sd,doubts".split(",")
    pelvises = [r for r in rows[1:] if r[3] == "pelvis"]
    assert len(pelvises) == 2 and len(rows) == 1 + 2 * 17     # the man on the board, a bystander at the left edge
    pelvis = max(pelvises, key=lambda r: float(r[4]))          # the man: right of the bystander
    assert 3000 < float(pelvis[8]) < 4500   # cam01 stands about 3.5-4 m from the balance board


def test_several_people_get_distinct_ids(estimator):
    frame = estimator.predict_image(read_image(DATA / "basketball2.png"))
    assert len(frame.people) == 2
    assert sorted(p.id for p in frame.people) == [0, 1]
    assert all(1000 < p.root[2] < 10000 for p in frame.people)


def test_video_tracks_one_person_with_a_stable_id(tmp_path):
    out = tmp_path / "clip.json"
    viz = tmp_path / "clip.mp4"
    r = run_posecam("predict", DATA / "balance_cam01_30f.mp4", "-o", out, "--viz", viz, "--model", "lite")
    assert r.returncode == 0, r.stderr
    inp = json.loads(out.read_text())["inputs"][0]
    frames = inp["frames"]
    assert len(frames) == 30 and inp["fps"] == 60
    assert [f["index"] for f in frames] == list(range(30))
    assert abs(frames[6]["time"] - 0.1) < 1e-6
    # the man on the board (the tallest in the picture; a bystander stands at the left edge) keeps his id
    balancing = [max(f["people"], key=lambda p: p["bbox"][3] - p["bbox"][1]) for f in frames]
    assert len({p["id"] for p in balancing}) == 1
    roots = np.array([p["root"] for p in balancing])
    assert np.abs(np.diff(roots, axis=0)).max() < 250   # smooth: no jumps between frames
    import cv2

    cap = cv2.VideoCapture(str(viz))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 30


def test_skeleton_33_and_image_viz(tmp_path):
    out, viz = tmp_path / "p.json", tmp_path / "p.png"
    r = run_posecam("predict", DATA / "basketball2.png", "--skeleton", "33", "-o", out, "--viz", viz)
    assert r.returncode == 0, r.stderr
    doc = json.loads(out.read_text())
    assert len(doc["joints"]) == 33 and doc["joints"][0] == "nose"
    import cv2

    assert cv2.imread(str(viz)).shape == (480, 640, 3)


def test_summary_without_output():
    r = run_posecam("predict", DATA / "basketball2.png", "--model", "lite")
    assert r.returncode == 0, r.stderr
    assert "basketball2.png" in r.stdout and "intrinsics (default)" in r.stdout


def test_no_person_is_a_warning_not_an_error(tmp_path):
    out = tmp_path / "fruits.json"
    r = run_posecam("predict", DATA / "fruits.jpg", "-o", out)
    assert r.returncode == 0
    assert "no person found" in r.stderr
    assert json.loads(out.read_text())["inputs"][0]["frames"][0]["people"] == []


def test_api_on_a_numpy_image_with_lite_model():
    est = PoseEstimator(EstimatorOptions(model="lite", max_people=1))
    frame = est.predict_image(read_image(DATA / "basketball2.png"))
    assert len(frame.people) == 1 and frame.people[0].keypoints_3d.shape == (17, 3)
