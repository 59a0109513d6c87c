"""Someone in the dark (an under-exposed or backlit video), whom the detector misses in the plain
image, is found once its lightness is equalised, and nobody is made up where the image is light."""

import cv2
import numpy as np

from conftest import DATA
from posecam import PoseEstimator
from posecam.geometry.boxes import box_iou
from posecam.inference.detector import detect_any_turn, detect_in_the_dark, load_detector
from posecam.io.media import open_media

VIDEO = DATA / "balance_cam01_30f.mp4"
NIGHT = 0.06   # the light left: a camera at dusk


def _frames() -> list[np.ndarray]:
    return [image for _, _, image in open_media(VIDEO).frames()]


def test_someone_in_the_dark_is_found_where_the_plain_image_hides_him():
    detector = load_detector("movenet")
    plain = _frames()[0]
    (athlete,) = [d for d in detector(plain) if d.score >= detector.start_score and d.box[3] - d.box[1] > 300]
    dark = (plain * NIGHT).astype(np.uint8)
    assert not [d for d in detect_any_turn(detector, dark) if d.score >= detector.start_score]
    found = [d for d in detect_in_the_dark(detector, dark) if d.score >= detector.start_score]
    assert found and box_iou(athlete.box, np.array([d.box for d in found])).max() > 0.5


def test_nobody_is_made_up_in_a_light_photo():
    """box.png (a cereal box, no person): with its lightness equalised the detector finds a
    person there, who stands in the light, so the plain image would have shown them."""
    detector = load_detector("movenet")
    image = cv2.cvtColor(cv2.imread(str(DATA / "box.png")), cv2.COLOR_BGR2RGB)
    lab = cv2.cvtColor(image, cv2.COLOR_RGB2LAB)
    lab[..., 0] = cv2.createCLAHE(clipLimit=3.0, tileGridSize=(8, 8)).apply(lab[..., 0])
    equalised = cv2.cvtColor(lab, cv2.COLOR_LAB2RGB)
    assert [d for d in detect_any_turn(detector, equalised) if d.score >= detector.start_score]
    assert not [d for d in detect_in_the_dark(detector, image) if d.score >= detector.start_score]
    assert PoseEstimator().predict_image(image).people == []


def test_a_video_filmed_at_dusk_keeps_its_athlete_on_every_frame_under_one_id(tmp_path):
    frames = _frames()
    h, w = frames[0].shape[:2]
    video = tmp_path / "dusk.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 60, (w, h))
    for f in frames:
        writer.write(cv2.cvtColor((f * NIGHT).astype(np.uint8), cv2.COLOR_RGB2BGR))
    writer.release()
    result = PoseEstimator().predict_file(video)
    tall = [[p for p in f.people if p.bbox[3] - p.bbox[1] > 300] for f in result.frames]
    assert all(len(people) == 1 for people in tall), [len(p) for p in tall]
    assert len({people[0].id for people in tall}) == 1
