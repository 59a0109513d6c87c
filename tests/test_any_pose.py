"""People in any orientation: real photos turned by 90 and 180 degrees give the same people,
with their skeletons on them, as the upright photos."""

import numpy as np
import pytest

from conftest import DATA
from posecam import PoseEstimator
from posecam.inference.detector import turned_back
from posecam.io.media import read_image


@pytest.fixture(scope="module")
def estimator():
    return PoseEstimator()


def test_turned_back_undoes_numpy_quarter_turns():
    image = np.arange(12).reshape(3, 4)
    for turns in (1, 2, 3):
        turned = np.rot90(image, turns)
        ys, xs = np.mgrid[:turned.shape[0], :turned.shape[1]]
        back = turned_back(np.stack([xs.ravel(), ys.ravel()], axis=1), turns, 4, 3).astype(int)
        assert (image[back[:, 1], back[:, 0]] == turned.ravel()).all()


@pytest.mark.parametrize("turns", [1, 2])
@pytest.mark.parametrize("photo", ["messi5.jpg", "basketball2.png"])
def test_turned_photo_gives_the_same_people_and_skeletons(estimator, photo, turns):
    image = read_image(DATA / photo)
    h, w = image.shape[:2]
    upright = estimator.predict_image(image).people
    turned = estimator.predict_image(np.ascontiguousarray(np.rot90(image, turns))).people
    assert len(upright) >= 1 and len(turned) == len(upright)
    for person in upright:
        height = np.ptp(person.keypoints_2d[:, 1])
        # the turned photo's skeleton, carried back onto the upright photo, lies on this person
        errors = [np.median(np.linalg.norm(turned_back(q.keypoints_2d, turns, w, h) - person.keypoints_2d, axis=1))
                  for q in turned]
        assert min(errors) < 0.05 * height, (photo, turns, errors, height)
