"""The second look for people (NanoDet, posecam.tracking.second_look) on real photos."""

import numpy as np
import pytest

from conftest import DATA
from posecam.geometry.boxes import box_iou
from posecam.inference.detector import load_detector, load_second_look
from posecam.io.media import read_image
from posecam.tracking import Tracker, TrackerOptions
from posecam.tracking.schedule import DetectorRun
from posecam.tracking.second_look import due, second_look

PHOTOS = (DATA / "basketball2.png", DATA.parents[1] / "examples" / "balance.jpg")


@pytest.fixture(scope="module")
def detectors():
    return load_second_look(), load_detector("movenet")


@pytest.mark.parametrize("photo", PHOTOS, ids=lambda p: p.name)
def test_nanodet_boxes_the_people_movenet_finds(detectors, photo):
    """Two people in each photo: NanoDet's decoded boxes (letterbox, cell centres, side
    distributions) lie on MoveNet's, IoU 0.8 or more, and are as many."""
    nanodet, movenet = detectors
    image = read_image(photo)
    boxes, people = nanodet(image), movenet(image, 40)
    assert len(people) == 2
    iou = box_iou(np.array([b.box for b in boxes]), np.array([d.box for d in people]))
    assert len(boxes) == 2 and (iou.max(axis=0) >= 0.8).all()


@pytest.mark.parametrize("photo", PHOTOS, ids=lambda p: p.name)
def test_a_person_the_detector_missed_is_read_on_a_crop_about_nanodets_box(detectors, photo):
    """Hand it MoveNet's detections less one: the second look gives back that person alone,
    with keypoints MoveNet read on its crop carried back onto them (their box within IoU 0.7
    of the one found on the whole photo)."""
    nanodet, movenet = detectors
    image = read_image(photo)
    people = movenet(image, 40)
    for missed in range(len(people)):
        found = second_look(nanodet, movenet, image, [d for i, d in enumerate(people) if i != missed], [])
        assert len(found) == 1
        assert box_iou(found[0].box, people[missed].box[None])[0, 0] >= 0.7
        assert (found[0].keypoint_scores >= 0.3).sum() >= 8


def test_the_second_look_is_due_only_while_someone_followed_is_lost(detectors):
    """No loss, no second look; someone confirmed and lost while nobody else is followed: on
    every search of the whole image, never on a search around some people."""
    _, movenet = detectors
    image = read_image(PHOTOS[0])
    tracker = Tracker(TrackerOptions(confirm_hits=1, confirm_frames=1), fps=30.0)
    tracks = tracker.begin_frame(movenet(image, 40), image)
    tracker.end_frame(tracks, [True] * len(tracks), [t.keypoints for t in tracks],
                      [t.keypoint_scores for t in tracks], [t.roi for t in tracks])
    assert not due(tracker, DetectorRun([]), 30.0)
    tracks = tracker.begin_frame(None)
    tracker.end_frame(tracks, [False] * len(tracks), [t.keypoints for t in tracks],
                      [t.keypoint_scores for t in tracks], [t.roi for t in tracks])
    assert not tracker.active() and tracker.missing_people()
    assert due(tracker, DetectorRun([]), 30.0)
    assert not due(tracker, DetectorRun(tracker.tracks[:1]), 30.0)
    assert not due(tracker, None, 30.0)
