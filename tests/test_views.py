"""The one prediction path: a take's views predicted by one estimator, each with its own camera's
intrinsics; `--out-dir` writes what `-o` writes; fuse's options reach the videos."""

import json
import warnings

import pytest

from conftest import DATA, EXAMPLES, run_posecam
from posecam.errors import InputError
from posecam.geometry.camera import CameraCalibration, Intrinsics
from posecam.io.calibration import write_toml
from posecam.io.intrinsics import IntrinsicsOptions
from posecam.io.poses import read_poses, write_poses
from posecam.multiview.take_check import check_lengths
from posecam.multiview.options import FuseOptions
from posecam.views import load_views, view_intrinsics

VIEWS = [str(DATA / "messi5.jpg"), str(EXAMPLES / "balance.jpg")]   # 548x342 and 1080x1920


def _calibration(tmp_path):
    """Two cameras with focal lengths no default lens has, sized like the two views."""
    cams = [CameraCalibration("left", (548, 342), Intrinsics(401.0, 402.0, 270.0, 170.0)),
            CameraCalibration("right", (1080, 1920), Intrinsics(1501.0, 1502.0, 540.0, 950.0))]
    path = tmp_path / "calib.toml"
    write_toml(path, cams)
    return path


def test_each_view_gets_its_own_camera_from_one_estimator(estimator, tmp_path):
    calib = _calibration(tmp_path)
    recs = load_views(VIEWS, intrinsics=IntrinsicsOptions(file=str(calib), camera="left,right"), estimator=estimator)
    assert [(r.intrinsics.fx, r.intrinsics.source) for r in recs] == [
        (401.0, "file:calib.toml#left"), (1501.0, "file:calib.toml#right")]
    assert all(r.frames[0].people for r in recs)     # the man first (the tallest); a bystander in some views
    # the same pose, lifted with a focal length 1501 / 1681.2 of the lab's: the pinhole puts it nearer
    lab = estimator.predict_file(VIEWS[1], IntrinsicsOptions(file=str(EXAMPLES / "cam01_intrinsics.json")))
    ratio = recs[1].frames[0].people[0].root[2] / lab.frames[0].people[0].root[2]
    assert ratio == pytest.approx(1501.0 / 1681.24, rel=0.05)


def test_camera_names_must_match_the_videos(tmp_path):
    calib = str(_calibration(tmp_path))
    with pytest.raises(InputError, match="names 2 cameras for 3 views"):
        view_intrinsics(["a.mp4", "b.mp4", "c.mp4"], IntrinsicsOptions(file=calib, camera="left,right"))
    one = view_intrinsics(["a.mp4", "b.mp4"], IntrinsicsOptions(file=calib, camera="right"))
    assert [o.camera for o in one] == ["right", "right"]
    flags = view_intrinsics(["a.mp4", "b.mp4"], IntrinsicsOptions(fx=900.0))
    assert [o.fx for o in flags] == [900.0, 900.0] and all(o.file is None for o in flags)


def test_lengths_are_compared_from_the_headers_before_any_prediction(estimator, tmp_path):
    """Offsets of up to 10 frames given: a 30-frame video against a 25-frame pose file is read
    (fusing them says they differ: FusionResult.warnings); against a 5-frame one (past those
    offsets): refused from the video's header, nothing predicted."""
    from dataclasses import replace

    rec = estimator.predict_file(EXAMPLES / "balance.jpg")
    rec.frames = [replace(rec.frames[0], index=i, time=i / 30) for i in range(25)]
    write_poses(tmp_path / "side.json", [rec])
    video = str(DATA / "balance_cam01_30f.mp4")
    given = FuseOptions(offsets=[0, 10])
    recs = load_views([video, str(tmp_path / "side.json")], estimator=estimator, fuse=given)
    assert [len(r.frames) for r in recs] == [30, 25]
    rec.frames = rec.frames[:5]
    write_poses(tmp_path / "short.json", [rec])
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        with pytest.raises(InputError, match=r"different lengths \(balance_cam01_30f.mp4 30, short.json 5 frames\)"):
            load_views([video, str(tmp_path / "short.json")], fuse=given, on_frame=lambda *a: pytest.fail("predicted"))
    assert not seen


@pytest.mark.parametrize("lengths, offsets, shared", [
    ((100, 88), [0, -11.77], None),     # 12 frames cut off the second view's start: lined up, a warning
    ((100, 88), [12.4, 0], None),       # the same, the first view's offset given instead
    ((100, 60), [0, 30], None),         # started earlier and stopped earlier: 30 frames of 60 shared
    ((100, 60), [0, 45], 15),           # 15 of 60 shared: not one take, or the offsets are wrong
    ((100, 30), [0, -90], 10),          # the second view starts 90 frames into the first: 10 shared
])
def test_offsets_given_line_up_views_of_different_lengths(lengths, offsets, shared):
    """Views cut apart by hand: with the offsets given, what counts is the frames they share."""
    if shared is None:
        assert "differ in length" in check_lengths(["a", "b"], list(lengths), FuseOptions(offsets=offsets))
    else:
        with pytest.raises(InputError, match=f"shares only {shared} of its frames"):
            check_lengths(["a", "b"], list(lengths), FuseOptions(offsets=offsets))


@pytest.mark.slow
def test_out_dir_writes_what_dash_o_writes(tmp_path):
    """`--out-dir` (the batch task) and `-o` (the command) stream through one path: the same
    smoothed frames, byte for byte past the header."""
    video = DATA / "balance_cam01_30f.mp4"
    (tmp_path / "dir").mkdir()
    r = run_posecam("predict", video, "--out-dir", tmp_path / "dir", "--fx", "1500")
    assert r.returncode == 0, r.stderr
    r = run_posecam("predict", video, "-o", tmp_path / "one.json", "--fx", "1500")
    assert r.returncode == 0, r.stderr
    a, b = (json.loads(p.read_text()) for p in (tmp_path / "dir" / "balance_cam01_30f.json", tmp_path / "one.json"))
    assert a["inputs"][0]["intrinsics"]["fx"] == 1500.0
    assert a == b
    raw = run_posecam("predict", video, "-o", tmp_path / "raw.json", "--fx", "1500", "--no-smooth")
    assert raw.returncode == 0, raw.stderr
    assert read_poses(tmp_path / "raw.json")[0].frames[3].people[0].keypoints_3d.tolist() != \
        read_poses(tmp_path / "one.json")[0].frames[3].people[0].keypoints_3d.tolist()   # smoothing did something


@pytest.mark.parametrize("args, code, words", [
    (["--calibration", "{calib}", "--intrinsics", "{calib}"], 2, "--calibration gives every camera's intrinsics"),
    (["--camera", "left"], 2, "give the file too"),
    (["--detector", "nope"], 2, "Invalid value for '--detector'"),
    (["--min-presence", "2"], 2, "--min-presence': '2' is not a finite number >= 0 and <= 1"),
    (["--max-people", "0"], 2, "--max-people"),
])
def test_fuse_takes_predicts_options_and_checks_them_before_any_work(args, code, words, tmp_path):
    from conftest import invoke_posecam

    calib = _calibration(tmp_path)
    r = invoke_posecam("fuse", *VIEWS, *(a.format(calib=calib) for a in args), "-o", tmp_path / "x.json")
    assert r.exit_code == code and words in r.stderr, r.stderr
    assert r.stderr.startswith("posecam: error:") and len(r.stderr.splitlines()) == 1
    assert not (tmp_path / "x.json").exists()


def test_pose_files_with_joints_posecam_does_not_know_are_refused_in_one_line(estimator, tmp_path):
    """17 joints under other names (or in another order) have no pelvis posecam could find: the
    file is refused when read, not with a traceback halfway through fusion."""
    from conftest import invoke_posecam

    write_poses(tmp_path / "a.json", [estimator.predict_file(EXAMPLES / "balance.jpg")])
    doc = json.loads((tmp_path / "a.json").read_text())
    doc["joints"] = doc["joints"][1:] + doc["joints"][:1]          # the same names, another order
    (tmp_path / "b.json").write_text(json.dumps(doc))
    with pytest.raises(InputError, match="b.json.*neither posecam's 17 joints nor the 33"):
        read_poses(tmp_path / "b.json")
    r = invoke_posecam("fuse", tmp_path / "a.json", tmp_path / "b.json", "-o", tmp_path / "x.json")
    assert r.exit_code == 2 and "neither posecam's 17 joints" in r.stderr and len(r.stderr.splitlines()) == 1, r.stderr


@pytest.mark.slow
def test_fuse_views_are_predicted_with_the_options_given(estimator):
    """The detection options reach every view: the two-person clip gives two people a frame
    with the defaults and one with max_people=1, from one estimator built for the options."""
    from posecam.estimate import EstimatorOptions, shared_estimator

    views = [str(DATA / "balance_cam01_30f.mp4"), str(DATA / "two_people_cam03_30f.mp4")]
    default = load_views(views, estimator=estimator)
    one = load_views(views, EstimatorOptions(max_people=1))
    assert max(len(f.people) for f in default[1].frames) == 2
    assert max(len(f.people) for r in one for f in r.frames) == 1
    assert shared_estimator(EstimatorOptions(max_people=1)) is shared_estimator(EstimatorOptions(max_people=1))


def test_a_rig_given_without_its_file_lifts_the_pose_files_as_its_file_does():
    """load_views(rig=Rig) relifts each pose file through its camera, as the calibration's file
    does: before, a Rig alone left the poses where the default lens had put them."""
    from posecam.io.calibration import read_calibration

    calib = DATA / "pose2sim_Calib_scene.toml"
    views = [str(DATA / "two_people_50f" / f"cam0{i}.json") for i in (1, 2)]
    rig = read_calibration(calib)
    by_file = load_views(views, calibration=str(calib), rig=rig)
    by_rig, as_read = load_views(views, rig=rig), load_views(views)
    for f, r, a in zip(by_file, by_rig, as_read):
        assert (r.intrinsics.fx, r.intrinsics.cx) == (f.intrinsics.fx, f.intrinsics.cx)
        pairs = [(p, q, s) for fp, fq, fs in zip(f.frames, r.frames, a.frames)
                 for p, q, s in zip(fp.people, fq.people, fs.people)]
        assert len(pairs) >= 50
        assert max(abs(p.keypoints_3d - q.keypoints_3d).max() for p, q, _ in pairs) < 1e-6
        assert max(abs(p.keypoints_3d - s.keypoints_3d).max() for p, _, s in pairs) > 50   # the lens moved them


@pytest.mark.parametrize("kwargs, words", [
    ({"intrinsics": IntrinsicsOptions(fx=1500.0)}, "--calibration gives every camera's intrinsics"),
    ({"chain": "stride", "fuse": FuseOptions(sync=True)}, "--stride does not go with --sync auto"),
])
def test_the_library_refuses_what_the_command_refuses(kwargs, words):
    """The checks between options live in load_views, which the command and the API both call."""
    from posecam.io.calibration import read_calibration
    from posecam.io.media import FrameSelection
    from posecam.options import PredictOptions

    views = [str(DATA / "two_people_50f" / f"cam0{i}.json") for i in (1, 2)]
    if kwargs.get("chain") == "stride":
        kwargs = {**kwargs, "chain": PredictOptions(frames=FrameSelection(stride="2"))}
    else:
        kwargs = {**kwargs, "rig": read_calibration(DATA / "pose2sim_Calib_scene.toml")}
    with pytest.raises(InputError, match=words):
        load_views(views, **kwargs)


def test_a_camera_name_not_in_the_calibration_is_named_with_the_closest(tmp_path):
    """--camera cam01 on a calibration naming cam_01: the error names the flag's value and suggests."""
    text = (DATA / "pose2sim_Calib_scene.toml").read_text().replace("int_cam01_img", "cam_01")
    calib = tmp_path / "calib.toml"
    calib.write_text(text)
    run = run_posecam("predict", EXAMPLES / "balance.jpg", "--intrinsics", calib, "--camera", "cam01")
    assert run.returncode != 0
    assert run.stderr.strip().splitlines()[-1] == (
        "posecam: error: --camera cam01: the calibration has no camera 'cam01' (its cameras: cam_01, int_cam02_img, "
        "int_cam03_img, int_cam04_img); did you mean cam_01?")
