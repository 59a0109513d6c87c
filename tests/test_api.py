"""One answer per input: the Python API with its defaults gives what the `predict` command gives.

The yardstick is the command's own output (`posecam predict -o FILE.json`), read back; the
API's results are compared with it joint by joint, person-frame by person-frame.
"""

import dataclasses
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from conftest import run_posecam
from posecam import PredictOptions
from posecam.errors import PosecamWarning
from posecam.io.media import read_image
from posecam.io.poses import read_poses

DATA = Path(__file__).parent / "data"
CLIP = DATA / "two_people_cam03_30f.mp4"   # two people, 30 frames of the two-person take
TOLERANCE_MM = 1.0                          # the JSON rounds to 0.1 mm


def _farthest(a, b) -> float:
    """The largest distance (mm) between the same person's joints in two recordings' frames,
    which must hold the same frames and the same people."""
    assert [f.index for f in a.frames] == [f.index for f in b.frames]
    worst = 0.0
    for fa, fb in zip(a.frames, b.frames):
        assert sorted(p.id for p in fa.people) == sorted(p.id for p in fb.people), fa.index
        for p in fa.people:
            q = next(q for q in fb.people if q.id == p.id)
            assert np.isfinite(p.keypoints_3d).all() == np.isfinite(q.keypoints_3d).all()
            worst = max(worst, float(np.nanmax(np.linalg.norm(p.keypoints_3d - q.keypoints_3d, axis=-1))))
    return worst


@pytest.fixture(scope="module")
def command_json(tmp_path_factory):
    out = tmp_path_factory.mktemp("api") / "clip.json"
    run = run_posecam("predict", str(CLIP), "-o", str(out))
    assert run.returncode == 0, run.stderr
    return read_poses(out)[0]


def test_predict_file_with_its_defaults_is_the_command(estimator, command_json):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        api = estimator.predict_file(CLIP)
    assert sum(len(f.people) for f in api.frames) >= 50            # both people, most frames
    assert _farthest(api, command_json) <= TOLERANCE_MM
    # the metric stage ran, and its warning reached the caller as it reaches the console
    assert {p.height_source for f in api.frames for p in f.people} == \
        {p.height_source for f in command_json.frames for p in f.people} != {""}
    assert any(issubclass(w.category, PosecamWarning) and str(CLIP) in str(w.message) for w in caught)
    # without the chain's later stages the poses are far off the command's: the test can fail
    raw = estimator.predict_file(CLIP, options=PredictOptions(smooth=False, metric=None))
    assert _farthest(raw, command_json) > 10 * TOLERANCE_MM


def test_track_with_its_defaults_is_the_folder_of_its_frames(estimator, command_json, tmp_path):
    cap = cv2.VideoCapture(str(CLIP))
    frames = []
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        frames.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
        cv2.imwrite(str(tmp_path / f"frame_{len(frames) - 1:04d}.png"), bgr)
    folder = estimator.predict_file(tmp_path)
    tracked = list(estimator.track(frames))
    assert [f.time for f in tracked] == [f.time for f in folder.frames]
    assert _farthest(dataclasses.replace(folder, frames=tracked), folder) <= TOLERANCE_MM


def test_predict_image_is_predict_file_of_the_photo(estimator):
    photo = DATA / "basketball2.png"
    frame = estimator.predict_image(read_image(photo))
    rec = estimator.predict_file(photo)
    assert len(frame.people) >= 2
    by_id = {p.id: p for p in rec.frames[0].people}
    for p in frame.people:
        q = by_id[p.id]
        assert p.doubts == q.doubts and p.height_source == q.height_source
        assert np.nanmax(np.abs(p.keypoints_3d - q.keypoints_3d)) <= TOLERANCE_MM


def test_the_commands_flags_take_their_defaults_from_the_options():
    from posecam.commands.predict import predict_command
    from posecam.options import EstimatorOptions

    defaults = {p.name: p.default for p in predict_command.params}
    assert defaults["smooth"] is PredictOptions().smooth
    assert defaults["floor"] is PredictOptions().metric.floor
    for name in ("model", "detector", "skeleton", "max_people", "min_presence", "device"):
        assert defaults[name] == getattr(EstimatorOptions(), name), name


@pytest.mark.demo
@pytest.mark.slow
def test_fusing_the_videos_is_fusing_predicts_pose_files_of_them(tmp_path):
    """The two-person take through the lab calibration, offsets given: fuse on the videos and fuse
    on the JSON `posecam predict` writes of each (through the same camera) agree to the JSON's
    rounding."""
    take = Path(__file__).parent.parent / "examples" / "demo" / "multi"
    calib, cams = str(take / "Calib.qca.txt"), ("cam01", "cam02", "cam03", "cam04")
    fuse = ("--calibration", calib, "--offsets", "0,-1,4,0")
    for cam in cams:
        run = run_posecam("predict", str(take / f"{cam}.mp4"), "--end", "40", "--intrinsics", calib, "--camera", cam,
                          "-o", str(tmp_path / f"{cam}.json"))
        assert run.returncode == 0, run.stderr
    runs = [run_posecam("fuse", *views, *fuse, "-o", str(tmp_path / out)) for views, out in
            (([str(take / f"{c}.mp4") for c in cams] + ["--end", "40"], "videos.json"),
             ([str(tmp_path / f"{c}.json") for c in cams], "files.json"))]
    assert all(r.returncode == 0 for r in runs), [r.stderr for r in runs]
    videos, files = (read_poses(tmp_path / out)[0] for out in ("videos.json", "files.json"))
    assert sum(len(f.people) for f in videos.frames) >= 60
    assert _farthest(videos, files) <= TOLERANCE_MM



def test_an_input_without_anyone_is_a_warning_to_an_api_caller_too(estimator, tmp_path):
    """A photo with nobody in it (fruits.jpg): predict_image, predict_file and a stream each warn
    why, once, with the line the command prints; a photo with people warns nothing of the kind."""
    photo = DATA / "fruits.jpg"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        frame = estimator.predict_image(read_image(photo))
        rec = estimator.predict_file(photo)
        list(estimator.stream_file(photo).poses())
        estimator.predict_file(DATA / "messi5.jpg")
    lines = [str(w.message) for w in caught if issubclass(w.category, PosecamWarning) and "no person" in str(w.message)]
    assert frame.people == [] and rec.frames[0].people == []
    assert lines == ["no person found: the detector found nobody above --min-detection-score "
                     f"{estimator.min_detection_score:g}"] + [f"no person found in {photo}: the detector found nobody "
                                                              f"above --min-detection-score {estimator.min_detection_score:g}"] * 2
    run = run_posecam("predict", photo, "-o", tmp_path / "f.json")
    assert [line for line in run.stderr.splitlines() if "no person" in line] == [f"posecam: warning: {lines[1]}"], run.stderr


def test_fuse_recordings_with_its_defaults_is_the_fuse_command(tmp_path):
    """The two-person take's four pose files (50 frames): `posecam fuse` with its defaults and
    `fuse_recordings(read_poses(...), FuseOptions())` give the same fused joints (to the JSON's
    rounding, angles included) and the same warnings."""
    from posecam import FuseOptions, fuse_recordings

    views = [DATA / "two_people_50f" / f"cam0{i}.json" for i in (1, 2, 3, 4)]
    run = run_posecam("fuse", *views, "--angles", "-o", tmp_path / "fused.json")
    assert run.returncode == 0, run.stderr
    command = read_poses(tmp_path / "fused.json")[0]
    result = fuse_recordings([read_poses(v)[0] for v in views], FuseOptions(angles=True))
    assert _farthest(result.recording, command) <= TOLERANCE_MM
    assert sum(len(f.people) for f in command.frames) >= 60
    for fa, fb in zip(result.recording.frames, command.frames):
        for p in fa.people:
            q = next(q for q in fb.people if q.id == p.id)
            assert p.angles.keys() == q.angles.keys() and p.angles
            assert max(abs(p.angles[k] - q.angles[k]) for k in p.angles if np.isfinite(p.angles[k])) < 0.1
    said = [line.removeprefix("posecam: warning: ") for line in run.stderr.splitlines() if "warning" in line]
    assert said == result.warnings


def test_predict_files_takes_a_folder_of_photos_as_the_command_does(estimator, tmp_path):
    """`predict_files(["photos/"])` gives one recording per photo, as `posecam predict photos/ -o`
    writes them; `predict_file("photos/")` refuses the folder and says why."""
    from posecam.errors import InputError

    folder = tmp_path / "photos"
    folder.mkdir()
    for name in ("messi5.jpg", "basketball2.png"):
        (folder / name).write_bytes((DATA / name).read_bytes())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        recs = estimator.predict_files([folder])
    run = run_posecam("predict", folder, "-o", tmp_path / "photos.json")
    assert run.returncode == 0, run.stderr
    command = read_poses(tmp_path / "photos.json")
    assert [Path(r.source).name for r in recs] == [Path(r.source).name for r in command] == ["basketball2.png", "messi5.jpg"]
    for r, c in zip(recs, command):
        assert len(r.frames[0].people) == len(c.frames[0].people) >= 1
        assert _farthest(r, c) <= TOLERANCE_MM
    with pytest.raises(InputError, match="give each photo as an input"):
        estimator.predict_file(folder)
