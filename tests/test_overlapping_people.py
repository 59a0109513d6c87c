"""Two people one crop confuses: the pose model gives the crop of a man passing in front of a
woman her pose; posed again with her painted over, he gets his own."""

import cv2
import numpy as np
import pytest

from conftest import DATA
from posecam import PoseEstimator
from posecam.inference.paint import GREY, painted_over, under
from posecam.inference.roi import Roi
from posecam.tracking import Track, alike
from posecam.tracking.motion import BoxKalman

# tests/data/two_people_cam03_088.jpg (frame 88 of the two-person take's cam03, rows 280-1339,
# columns 0-899): the man walks past in front of the woman. Marked by hand on the image:
MAN_FEET = np.array([390, 770, 530, 910])      # x0, y0, x1, y1 around both his feet
WOMAN_FEET = np.array([230, 640, 360, 760])
WOMAN_CROP = Roi(291, 499, 682, -0.12)         # her crop as the tracker holds it (her own pose's)


@pytest.fixture(scope="module")
def scene():
    rgb = cv2.cvtColor(cv2.imread(str(DATA / "two_people_cam03_088.jpg")), cv2.COLOR_BGR2RGB)
    est = PoseEstimator()
    return est, rgb, est.pose_model(rgb, [WOMAN_CROP])[0]


def _inside(points: np.ndarray, box: np.ndarray) -> bool:
    return bool(((points >= box[:2]) & (points <= box[2:])).all())


def _track(est: PoseEstimator, pose, roi: Roi, hits: int) -> Track:
    idx = est._to_detector
    box = np.concatenate([pose.keypoints_2d.min(axis=0), pose.keypoints_2d.max(axis=0)])
    return Track(hits, roi, BoxKalman(box), pose.keypoints_2d[idx], pose.confidence[idx], hits=hits)


def test_painting_a_person_over_covers_their_limbs_and_leaves_the_image_alone():
    image = np.full((100, 100, 3), 10, np.uint8)
    points = np.array([[20.0, 20], [20, 80], [80, 80]])
    bones = np.array([[0, 1], [1, 2]])
    out, mask = painted_over(image, points, np.array([True, True, False]), bones)
    assert (image == 10).all()                             # a copy is painted
    assert (out[50, 20] == GREY).all()                     # the bone between two seen joints
    assert (out[80, 60] == 10).all()                       # not the one to a joint not seen
    assert (out[50, 60] == 10).all()
    assert mask[50, 20] and not mask[80, 60]
    assert under(mask, np.array([[20.0, 50], [60, 80], [-5, 50]])).tolist() == [True, False, False]


@pytest.mark.parametrize("cx", [280, 320, 360])
def test_a_man_whose_crop_gives_the_woman_behind_him_is_posed_again_with_her_painted_over(scene, cx):
    est, rgb, woman = scene
    idx = est._to_detector
    ankles = [est.pose_model.joints.index(n) for n in ("left_ankle", "right_ankle")]
    assert _inside(woman.keypoints_2d[ankles], WOMAN_FEET)
    his_crop = Roi(cx, 520, 800)                           # centred on him, tight
    his = est.pose_model(rgb, [his_crop])[0]
    woman_box = np.concatenate([woman.keypoints_2d.min(axis=0), woman.keypoints_2d.max(axis=0)])
    assert alike(his.keypoints_2d[idx], his.confidence[idx], woman.keypoints_2d[idx], woman.confidence[idx],
                 woman_box)                                # the model gives his crop her pose
    tracks = [_track(est, woman, WOMAN_CROP, hits=20), _track(est, his, his_crop, hits=10)]
    candidates = [woman, his]
    est._apart(rgb, tracks, candidates, [None, None])
    assert candidates[0] is woman                          # she, kept first, keeps hers
    again = candidates[1]
    assert _inside(again.keypoints_2d[ankles], MAN_FEET)   # his feet, not hers
    assert not alike(again.keypoints_2d[idx], again.confidence[idx], woman.keypoints_2d[idx],
                     woman.confidence[idx], woman_box)
    _, painted = painted_over(rgb, woman.keypoints_2d, woman.confidence >= 0.3, est._pose_bones)
    hidden = under(painted, again.keypoints_2d)
    assert hidden.any() and (again.confidence[hidden] == 0).all()   # his joints behind her paint: unseen
    assert (again.confidence[~hidden] > 0).any()


def test_the_person_kept_first_is_the_one_detected_most(scene):
    est, rgb, woman = scene
    his_crop = Roi(320, 520, 800)
    his = est.pose_model(rgb, [his_crop])[0]
    tracks = [_track(est, woman, WOMAN_CROP, hits=5), _track(est, his, his_crop, hits=10)]
    candidates = [woman, his]
    est._apart(rgb, tracks, candidates, [None, None])
    assert candidates[1] is his                            # the man, kept first, keeps the pose his crop gave
