"""The judge stage of one frame (`PoseEstimator._judge`, FramePolicy): a pose whose joints land on
a neighbour is posed again from the other crops (`crops_to_try`), on the two-person take."""

import warnings
from pathlib import Path

import numpy as np

from posecam import PredictOptions
from posecam.estimate import crops_to_try
from posecam.inference.detector import Detection

CLIP = Path(__file__).parent / "data" / "two_people_cam03_30f.mp4"   # two people, 30 frames (SOURCE.md)


def test_a_pose_on_the_neighbour_is_posed_again_from_another_crop(estimator):
    """In the clip's last frame the adult's crop gives a pose on the second person (its joints on
    her keypoints): tried again from his box, it is his, so both people are posed and nobody is
    dropped there as a pose on a neighbour. Without the retry the adult is dropped there."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = estimator.predict_file(CLIP, options=PredictOptions(smooth=False, metric=None))
    last = rec.frames[-1]
    assert len(last.people) == 2
    assert not [d for d in last.dropped if d.stage == "neighbour"]


def test_the_crops_to_try_start_upright_on_the_box_and_reach_past_a_cut_border():
    """Upright on the person's box first; past the border only where the border cuts the box;
    then the detector's crop turned a quarter either way and upside down."""
    from posecam.inference.roi import Roi

    roi, none = Roi(100.0, 200.0, 150.0, 0.1), np.zeros((0, 2))
    inside = Detection(0.9, np.array([50.0, 100.0, 150.0, 300.0]), none, np.zeros(0), roi)
    cut = Detection(0.9, np.array([0.0, 100.0, 150.0, 300.0]), none, np.zeros(0), roi, at_border=True)
    plain, past = crops_to_try(inside, 640, 480), crops_to_try(cut, 640, 480)
    assert len(plain) == 4 and len(past) == 5
    assert plain[0].angle == 0.0
    assert np.allclose([c.angle - roi.angle for c in plain[1:]], [np.pi / 2, -np.pi / 2, np.pi])


def test_a_doubted_pose_the_detector_agrees_with_is_kept():
    """With every pose doubted (--min-presence 1.0: the pose model's presence of a clear player
    is 0.999 at most), the poses that match the detector's keypoints of their person (OKS >=
    FramePolicy.agree_oks) are kept: both of basketball2's players, nobody dropped. Without the
    rule the player at 0.999 is dropped as "presence"."""
    from posecam import EstimatorOptions, PoseEstimator
    from posecam.io.media import read_image

    doubting = PoseEstimator(EstimatorOptions(min_presence=1.0))
    frame = doubting.predict_image(read_image(Path(__file__).parent / "data" / "basketball2.png"),
                                   options=PredictOptions(metric=None))
    assert len(frame.people) == 2 and not frame.dropped
