"""What the pose model did not see is not shown as seen: joints off the picture, under
MIN_CONFIDENCE, or hips with no knee seen are listed in the JSON's "unseen", 0 in the CSV's
"seen" column, and drawn apart; a photo whose lens is assumed says so once on stderr."""

import csv
import json

import cv2
import numpy as np
import pytest

from conftest import EXAMPLES, run_posecam
from test_exif import _exif_segment
from posecam.io.poses import read_poses
from posecam.viz.draw import UNSEEN, draw_people

LEGS = {"r_knee", "r_ankle", "l_knee", "l_ankle"}
LENS_WARNING = "mm-equivalent lens assumed"


def _crop(path, rows: slice, cols: slice):
    """A part of examples/balance.jpg (the man on the balance board, 1080x1920), written as a PNG:
    no EXIF, so no lens but the default or the one given."""
    cv2.imwrite(str(path), cv2.imread(str(EXAMPLES / "balance.jpg"))[rows, cols])
    return path


@pytest.fixture(scope="module")
def waist_up(tmp_path_factory):
    """The man cut off at the hips (his knees are at rows 900-920 of the photo, his wrists at 728):
    his legs and wrists out of the picture, the bystander left out. Predicted through a lens
    given, to JSON and to CSV."""
    folder = tmp_path_factory.mktemp("waist_up")
    photo = _crop(folder / "waist_up.png", slice(0, 720), slice(200, 700))
    for suffix in ("json", "csv"):
        run = run_posecam("predict", photo, "--fx", "1681", "-o", folder / f"poses.{suffix}")
        assert run.returncode == 0 and LENS_WARNING not in run.stderr, run.stderr
    doc = json.loads((folder / "poses.json").read_text())
    rows = list(csv.DictReader((folder / "poses.csv").open()))
    return photo, doc, rows


def test_joints_off_the_picture_or_invented_are_unseen_in_the_json(waist_up):
    _, doc, _ = waist_up
    (person,) = doc["inputs"][0]["frames"][0]["people"]
    width, height = doc["inputs"][0]["width"], doc["inputs"][0]["height"]
    joints = dict(zip(doc["joints"], zip(person["keypoints_2d"], person["confidence"])))
    off = {name for name, ((u, v), _) in joints.items() if not (0 <= u < width and 0 <= v < height)}
    assert any(joints[name][1] >= 0.5 for name in off), joints    # confident, yet off the picture
    assert off <= set(person["unseen"])
    assert LEGS <= set(person["unseen"])                          # invented under the cut
    # the hips the model placed on the picture's lower part, with no knee seen: the root is a guess
    assert {"pelvis", "r_hip", "l_hip"} <= set(person["unseen"])
    assert {"head", "nose", "thorax", "l_shoulder", "r_shoulder"}.isdisjoint(person["unseen"])


def test_the_csv_seen_column_is_the_json_unseen_list(waist_up):
    _, doc, rows = waist_up
    (person,) = doc["inputs"][0]["frames"][0]["people"]
    assert {row["joint"] for row in rows if row["seen"] == "0"} == set(person["unseen"])
    assert {row["seen"] for row in rows} == {"0", "1"}


def test_a_whole_person_has_every_joint_seen(tmp_path):
    out = tmp_path / "balance.json"
    run = run_posecam("predict", EXAMPLES / "balance.jpg", "--intrinsics", EXAMPLES / "cam01_intrinsics.json",
                      "-o", out)
    assert run.returncode == 0, run.stderr
    people = json.loads(out.read_text())["inputs"][0]["frames"][0]["people"]
    man = max(people, key=lambda p: p["bbox"][3] - p["bbox"][1])
    assert man["unseen"] == [] and min(man["confidence"]) >= 0.5


def test_unseen_joints_and_their_bones_are_drawn_apart(waist_up):
    photo, _, _ = waist_up
    (rec,) = read_poses(photo.parent / "poses.json")
    (person,) = rec.frames[0].people
    black = np.zeros((rec.height, rec.width, 3), np.uint8)
    drawn = draw_people(black, [person], rec.joints)
    at = {name: tuple(np.round(uv).astype(int)) for name, uv in zip(rec.joints, person.keypoints_2d)}

    def pixel(name: str) -> np.ndarray:
        u, v = at[name]
        return drawn[v, u]

    assert (pixel("thorax") == 255).all()                   # a seen joint: a filled white dot
    assert not (pixel("pelvis") == 255).all()               # the unseen root: a hollow ring

    def along(a: str, b: str) -> np.ndarray:
        """(60, 3) the pixels along the middle half of the bone a-b."""
        (u0, v0), (u1, v1) = at[a], at[b]
        t = np.linspace(0.25, 0.75, 60)
        return drawn[np.round(v0 + t * (v1 - v0)).astype(int), np.round(u0 + t * (u1 - u0)).astype(int)]

    solid = along("thorax", "l_shoulder")                   # a seen bone: solid, the left side's colour
    assert solid.any(axis=1).all() and (np.ptp(solid, axis=1) > 50).all()
    dashed = along("spine", "pelvis")                       # a bone to the unseen root: grey dashes
    lit = dashed.any(axis=1)
    assert lit.any() and not lit.all(), lit
    assert (np.ptp(dashed, axis=1) == 0).all() and dashed.max() <= max(UNSEEN)


def _lens_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if LENS_WARNING in line]


def test_a_photo_without_exif_or_lens_warns_once_that_the_lens_is_assumed(tmp_path):
    photo = _crop(tmp_path / "no_exif.png", slice(300, 1200), slice(150, 750))
    out = tmp_path / "p.json"
    run = run_posecam("predict", photo, "-o", out)
    assert run.returncode == 0, run.stderr
    k = json.loads(out.read_text())["inputs"][0]["intrinsics"]
    lines = _lens_lines(run.stderr)
    assert len(lines) == 1, run.stderr
    line = lines[0]
    assert line.startswith(f"posecam: warning: {photo}: ") and k["source"] == "default"
    assert "28 mm-equivalent" in line and f"fx = {k['fx']:.0f} px" in line and "--intrinsics" in line


def test_a_photo_with_its_lens_given_or_in_its_exif_does_not_warn(tmp_path):
    photo = _crop(tmp_path / "given.png", slice(300, 1200), slice(150, 750))
    given = run_posecam("predict", photo, "--fx", "1681", "-o", tmp_path / "given.json")
    jpeg = _crop(tmp_path / "exif.jpg", slice(300, 1200), slice(150, 750))
    data = jpeg.read_bytes()
    jpeg.write_bytes(data[:2] + _exif_segment(26, "II") + data[2:])     # a camera's EXIF: 26 mm-equivalent
    exif = run_posecam("predict", jpeg, "-o", tmp_path / "exif.json")
    assert given.returncode == exif.returncode == 0, given.stderr + exif.stderr
    assert _lens_lines(given.stderr) == _lens_lines(exif.stderr) == []
    assert json.loads((tmp_path / "exif.json").read_text())["inputs"][0]["intrinsics"]["source"] == "exif"
