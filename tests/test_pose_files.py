import csv
import json

import numpy as np
import pytest

from posecam.geometry.camera import Intrinsics
from posecam.errors import InputError
from posecam.io.poses import CSV_HEADER, read_poses, write_poses
from posecam.results import Frame, Person, Recording
from posecam.skeleton import H36M_JOINTS


def _recording() -> Recording:
    rng = np.random.default_rng(0)
    people = [Person(i, 0.9, np.array([1, 2, 300, 400.0]), rng.uniform(0, 500, (17, 2)),
                     rng.uniform(-900, 4000, (17, 3)), rng.uniform(0, 1, 17)) for i in range(2)]
    return Recording("clip.mp4", 1080, 1920, Intrinsics(1677, 1677, 540, 960, "flags"), H36M_JOINTS,
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
    assert np.allclose(back.frames[0].people[1].keypoints_3d, orig.frames[0].people[1].keypoints_3d, atol=0.05)


def test_csv_header_and_rows(tmp_path):
    path = tmp_path / "out.csv"
    write_poses(path, [_recording()])
    rows = list(csv.reader(path.open()))
    assert rows[0] == list(CSV_HEADER) == "source,frame,person,joint,u,v,x,y,z,confidence".split(",")
    assert len(rows) == 1 + 17 * 3
    assert rows[1][3] == "pelvis" and rows[18][2] == "1"


def test_not_a_pose_file(tmp_path):
    p = tmp_path / "x.json"
    p.write_text("[1, 2]")
    with pytest.raises(InputError):
        read_poses(p)
