"""`posecam predict` and the PoseEstimator API on real photos and a real video clip."""

import csv
import json
import re

import numpy as np

from conftest import DATA, EXAMPLES, run_posecam
from posecam import EstimatorOptions, PoseEstimator
from posecam.io.media import read_image
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
    assert rows[0] == "source,frame,person,joint,u,v,x,y,z,confidence,height,height_source,depth_sd,doubts,seen".split(",")
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


def test_non_square_pixels_put_the_person_on_the_keypoints_rays(tmp_path):
    """A camera-space golden that posecam's code does not compute: with an intrinsics file whose
    fy is 1.3 fx and whose principal point is off the centre, the root translation places the
    metric pose so that, over the joints weighted by their confidence (as the least-squares
    solve weighs them, 33 landmarks all written), the horizontal and vertical offsets of each
    trunk and leg joint from the ray of its own 2D keypoint cancel: sum w z (x / z - (u - cx) / fx) = 0 and
    sum w z (y / z - (v - cy) / fy) = 0, worked out here from the file's numbers (the pinhole
    model). fx in the place of fy leaves a mean vertical offset of 19 px (and the person
    280 mm nearer)."""
    fx, fy, cx, cy = 500.0, 650.0, 300.0, 100.0
    k = tmp_path / "k.json"
    k.write_text(json.dumps({"fx": fx, "fy": fy, "cx": cx, "cy": cy}))
    out = tmp_path / "messi.json"
    r = run_posecam("predict", DATA / "messi5.jpg", "--intrinsics", k, "--skeleton", "33", "-o", out)
    assert r.returncode == 0, r.stderr
    inp = json.loads(out.read_text())["inputs"][0]
    assert [inp["intrinsics"][n] for n in ("fx", "fy", "cx", "cy")] == [fx, fy, cx, cy]
    (person,) = inp["frames"][0]["people"]
    xyz, uv, w = (np.array(person[n]) for n in ("keypoints_3d", "keypoints_2d", "confidence"))
    assert len(xyz) == 33 and (xyz[:, 2] > 0).all() and (w > 0.5).sum() >= 20
    # the metric stage places the pose on the trunk and legs (posecam.scale.metric.CORE)
    names = json.loads(out.read_text())["joints"]
    w = w * np.isin(names, [f"{s}_{j}" for s in ("left", "right") for j in ("shoulder", "hip", "knee", "ankle")])
    off = (xyz[:, :2] / xyz[:, 2:] - np.stack([(uv[:, 0] - cx) / fx, (uv[:, 1] - cy) / fy], axis=1)) * [fx, fy]
    mean_off = (w * xyz[:, 2]) @ off / (w * xyz[:, 2]).sum()              # px, horizontal and vertical
    assert np.abs(mean_off).max() < 0.5, mean_off


def _drawn_labels(monkeypatch) -> list[str]:
    """The texts posecam.viz.draw puts on pictures from now on (each label is written twice,
    its outline then its fill: one entry per label)."""
    import cv2

    drawn, put_text = [], cv2.putText

    def recorded(image, text, *args, **kwargs):
        drawn.append(text)
        return put_text(image, text, *args, **kwargs)

    monkeypatch.setattr("posecam.viz.draw.cv2.putText", recorded)
    return drawn


def _written_labels(path) -> list[str]:
    """The label each written person would be drawn with: id and root depth in metres."""
    frames = json.loads(path.read_text())["inputs"][0]["frames"]
    return [f"#{p['id']} z={p['root'][2] / 1000:.2f} m" for f in frames for p in f["people"]]


def _same_labels(drawn: list[str], written: list[str]) -> bool:
    """Each label drawn twice (outline, fill), with the written id and depth. The file holds the
    depth to 0.1 mm, so a depth on a rounding boundary may print one centimetre apart."""
    def parsed(labels):
        return [(m[1], float(m[2])) for m in (re.fullmatch(r"(#\d+\??) z=(-?[\d.]+) m", t) for t in labels)]

    fill, outline, file = parsed(drawn[1::2]), parsed(drawn[::2]), parsed(written)
    return (fill == outline and len(fill) == len(file)
            and all(a[0] == b[0] and abs(a[1] - b[1]) <= 0.0101 for a, b in zip(fill, file)))


def test_the_depth_drawn_on_a_picture_is_the_depth_written(tmp_path, monkeypatch):
    """--viz draws each person at the metric scale the pose file is given (before: messi5's
    picture said z = 1.91 m, the pose model's size, where the file said 2187 mm)."""
    drawn = _drawn_labels(monkeypatch)
    out = tmp_path / "messi.json"
    r = run_posecam("predict", DATA / "messi5.jpg", "-o", out, "--viz", tmp_path / "messi.jpg")
    assert r.returncode == 0, r.stderr
    assert _same_labels(drawn, _written_labels(out)) and len(drawn) == 2


def test_the_depth_drawn_on_a_video_is_the_depth_written(tmp_path, monkeypatch):
    """A video's frames are drawn as they leave the last stage, smoothed as the pose file is
    (the stages hold them back; the frames are read a second time for it): frame by frame, the
    labels are the pose file's (before: drawn unsmoothed, up to 1 m off on a doubtful pose)."""
    drawn = _drawn_labels(monkeypatch)
    out = tmp_path / "clip.json"
    r = run_posecam("predict", DATA / "balance_cam01_30f.mp4", "--end", "12", "-o", out,
                    "--viz", tmp_path / "clip.mp4")
    assert r.returncode == 0, r.stderr
    written = _written_labels(out)
    assert len(written) >= 12 and _same_labels(drawn, written)


def test_summary_fits_80_columns_with_nothing_cut(tmp_path, monkeypatch):
    """The summary as a pipe or a log shows it (80 columns): no cell cut, every input's name
    whole (a long one folds onto a second line), the height's source in words."""
    import shutil

    monkeypatch.setenv("COLUMNS", "80")      # what rich takes off a terminal, whatever runs the tests
    long_name = tmp_path / "messi_at_the_camp_nou_in_the_2011_final.jpg"
    shutil.copy(DATA / "messi5.jpg", long_name)
    r = run_posecam("predict", long_name, DATA / "basketball2.png", "--height", "1.7")
    assert r.returncode == 0, r.stderr
    assert "…" not in r.stdout and max(len(line) for line in r.stdout.splitlines()) <= 80, r.stdout
    rows = [line.split("│") for line in r.stdout.splitlines() if line.startswith("│")]
    assert "".join(cells[1].strip() for cells in rows) == long_name.name + "basketball2.png" * 2, r.stdout
    assert sum("1.70 given" in line for line in r.stdout.splitlines()) >= 2, r.stdout
    header = " ".join(line for line in r.stdout.splitlines() if line.startswith("┃"))
    assert header.count(" mm ") == 4 and " m " in header and "±z" in header, header
    r = run_posecam("predict", long_name)       # one input: named in the title, no column for it
    assert r.returncode == 0, r.stderr
    assert "…" not in r.stdout and long_name.name in r.stdout, r.stdout
    assert re.search(r"│ +[12]\.\d\d model │", r.stdout), r.stdout          # the pose model's scale
    # no lens given: the depth's spread has the default lens's 30 % in it
    z, sd = (int(v) for v in re.search(r"│ +-?\d+ │ +-?\d+ │ +(\d+) │ +(\d+) │ +[01]\.\d\d │", r.stdout).groups())
    assert 0.3 < sd / z < 0.4, r.stdout
