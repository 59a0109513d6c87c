import csv
import json
import re

import numpy as np
import pytest

from posecam.geometry.camera import Intrinsics
from posecam.errors import InputError
from posecam.io.poses import CSV_HEADER, read_poses, write_poses
from posecam.results import Frame, Person, Recording
from posecam.skeleton import BLAZEPOSE_LANDMARKS, H36M_JOINTS, skeleton_of


def _recording() -> Recording:
    rng = np.random.default_rng(0)
    people = [Person(i, 0.9, np.array([1, 2, 300, 400.0]), rng.uniform(0, 500, (17, 2)),
                     rng.uniform(-900, 4000, (17, 3)), rng.uniform(0, 1, 17)) for i in range(2)]
    return Recording("clip.mp4", 1080, 1920, Intrinsics(1677, 1690, 541, 958, "flags"), H36M_JOINTS,
                     [Frame(0, 0.0, people), Frame(1, 1 / 60, people[:1])], model="blazepose-full", fps=60.0)


def test_json_has_the_documented_keys_and_round_trips(tmp_path):
    path = tmp_path / "out.json"
    write_poses(path, [_recording()])
    doc = json.loads(path.read_text())
    assert set(doc) >= {"posecam", "model", "joints", "inputs"}
    inp = doc["inputs"][0]
    assert set(inp) >= {"source", "width", "height", "intrinsics", "frames"}
    assert set(inp["intrinsics"]) >= {"fx", "fy", "cx", "cy", "source"}
    assert set(inp["frames"][0]) >= {"index", "time", "people"}
    assert set(inp["frames"][0]["people"][0]) >= {"id", "score", "bbox", "keypoints_2d", "keypoints_3d", "confidence", "root"}
    back = read_poses(path)[0]
    orig = _recording()
    assert back.joints == orig.joints and len(back.frames) == 2
    assert back.intrinsics == orig.intrinsics
    assert np.allclose(back.frames[0].people[1].keypoints_3d, orig.frames[0].people[1].keypoints_3d, atol=0.05)


def test_csv_header_and_rows(tmp_path):
    path = tmp_path / "out.csv"
    write_poses(path, [_recording()])
    rows = list(csv.reader(path.open()))
    assert rows[0] == list(CSV_HEADER) == "source,frame,person,joint,u,v,x,y,z,confidence,height,height_source,depth_sd,doubts,seen".split(",")
    assert len(rows) == 1 + 17 * 3
    assert rows[1][3] == "pelvis" and rows[18][2] == "1"


def test_not_a_pose_file(tmp_path):
    p = tmp_path / "x.json"
    p.write_text("[1, 2]")
    with pytest.raises(InputError):
        read_poses(p)


@pytest.mark.parametrize("field, value", [
    ("bbox", np.zeros(3)), ("keypoints_2d", np.zeros((17, 3))), ("keypoints_3d", np.zeros((16, 3))),
    ("confidence", np.zeros((17, 1))),
])
def test_person_checks_its_array_shapes(field, value):
    arrays = {"bbox": np.zeros(4), "keypoints_2d": np.zeros((17, 2)), "keypoints_3d": np.zeros((17, 3)),
              "confidence": np.zeros(17)}
    Person(0, 1.0, **arrays)
    with pytest.raises(ValueError, match=f"Person.{field}: expected shape"):
        Person(0, 1.0, **{**arrays, field: value})


def test_non_finite_values_are_null_in_json_and_empty_in_csv(tmp_path):
    rec = _recording()
    p = rec.frames[0].people[0]
    p.keypoints_3d[2] = np.nan
    p.keypoints_2d[3, 0] = np.inf
    write_poses(tmp_path / "o.json", [rec])
    write_poses(tmp_path / "o.csv", [rec])
    text = (tmp_path / "o.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    json.loads(text, parse_constant=lambda c: pytest.fail(f"non-standard JSON token {c}"))
    back = read_poses(tmp_path / "o.json")[0].frames[0].people[0]
    assert np.isnan(back.keypoints_3d[2]).all() and np.isnan(back.keypoints_2d[3, 0])
    assert np.isfinite(back.keypoints_3d[3]).all()
    rows = list(csv.reader((tmp_path / "o.csv").open()))
    assert rows[3][6:9] == ["", "", ""] and rows[4][4] == ""


@pytest.mark.parametrize("edit, words", [
    (lambda d: d["inputs"][0]["frames"][0]["people"][0].update(keypoints_3d=[[0, 0, 0]] * 16), "shape [16, 3]"),
    (lambda d: d["inputs"][0]["frames"][0]["people"][0].update(confidence=[0.5] * 18), "shape [18]"),
    (lambda d: d.update(joints=d["joints"][:16]), "expected [16, 2]"),
])
def test_joint_counts_must_match_the_declared_joints(tmp_path, edit, words):
    path = tmp_path / "p.json"
    write_poses(path, [_recording()])
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=re.escape(words)):
        read_poses(path)


def test_deeply_nested_pose_file_is_refused(tmp_path):
    path = tmp_path / "deep.json"
    path.write_text('{"joints": ' + "[" * 200000 + "]" * 200000 + "}")
    with pytest.raises(InputError, match="nested too deeply"):
        read_poses(path)


@pytest.mark.parametrize("joints, root", [(H36M_JOINTS, "pelvis"), (BLAZEPOSE_LANDMARKS, "mid_hip")])
def test_json_names_the_root_joint(tmp_path, joints, root):
    j = len(joints)
    person = Person(0, 0.9, np.zeros(4), np.zeros((j, 2)), np.ones((j, 3)), np.ones(j), skeleton=skeleton_of(joints))
    rec = Recording("a.jpg", 640, 480, Intrinsics(500, 500, 320, 240), joints, [Frame(0, 0.0, [person])])
    write_poses(tmp_path / "p.json", [rec])
    assert json.loads((tmp_path / "p.json").read_text())["root_joint"] == root
    unnamed = Person(0, 0.9, np.zeros(4), np.zeros((j, 2)), np.ones((j, 3)), np.ones(j))   # no skeleton: the 17 joints
    if j != 17:
        with pytest.raises(ValueError, match="give Person"):   # nothing guessed from the joint count
            unnamed.root
