import json

import pytest

from posecam.errors import InputError
from posecam.io.intrinsics import IntrinsicsOptions, resolve_intrinsics


def test_flags_win_and_default_principal_point_is_the_centre():
    k = resolve_intrinsics(IntrinsicsOptions(fx=1200.0), 1920, 1080)
    assert (k.fx, k.fy, k.cx, k.cy, k.source) == (1200.0, 1200.0, 960.0, 540.0, "flags")


def test_json_file_with_values_or_matrix(tmp_path):
    a = tmp_path / "a.json"
    a.write_text(json.dumps({"fx": 1000, "fy": 1010, "cx": 500, "cy": 400}))
    b = tmp_path / "b.json"
    b.write_text(json.dumps({"matrix": [[900, 0, 320], [0, 905, 240], [0, 0, 1]]}))
    ka = resolve_intrinsics(IntrinsicsOptions(file=str(a)), 1000, 800)
    kb = resolve_intrinsics(IntrinsicsOptions(file=str(b)), 640, 480)
    assert (ka.fx, ka.fy, ka.cx, ka.cy) == (1000, 1010, 500, 400) and ka.source == "file:a.json"
    assert (kb.fx, kb.fy, kb.cx, kb.cy) == (900, 905, 320, 240)


def test_default_is_a_28mm_equivalent_lens():
    k = resolve_intrinsics(IntrinsicsOptions(), 1080, 1920)
    assert k.source == "default" and 1300 < k.fx < 1500 and k.cx == 540


@pytest.mark.parametrize("content", ["{not json", json.dumps({"fx": 100}), json.dumps({"matrix": [[1, 2]]})])
def test_bad_json_is_refused(tmp_path, content):
    p = tmp_path / "k.json"
    p.write_text(content)
    with pytest.raises(InputError):
        resolve_intrinsics(IntrinsicsOptions(file=str(p)), 640, 480)


@pytest.mark.parametrize("opts, words", [
    (dict(fx=-3.0), "positive"),
    (dict(fx=1000.0, cx=5000.0, cy=240.0), "outside the 640x480 image"),
    (dict(file="/nonexistent/k.json"), "no such file"),
    (dict(fx=1e300), "field of view"),          # 0 degrees: a telescope
    (dict(fx=10.0), "field of view"),           # 176 degrees
    (dict(fx=500.0, fy=5000.0), "differ by more than"),
])
def test_nonsense_intrinsics_are_refused(opts, words):
    with pytest.raises(InputError, match=words):
        resolve_intrinsics(IntrinsicsOptions(**opts), 640, 480)


@pytest.mark.parametrize("opts, words", [
    (dict(fx=True), "must be a number"), (dict(fx="1000"), "must be a number"),
    (dict(fx=float("nan")), "finite"), (dict(fx=1000.0, cx=320.0), "together"),
    (dict(cx=320.0, cy=240.0), "need a focal length"), (dict(camera="cam01"), "give the file too"),
])
def test_options_that_cannot_go_together_are_refused_when_built(opts, words):
    with pytest.raises(InputError, match=words):
        IntrinsicsOptions(**opts)


@pytest.mark.parametrize("doc, words", [
    ({"fx": True, "cx": 320, "cy": 240}, "fx: must be a number"),
    ({"fx": "800", "cx": 320, "cy": 240}, "fx: must be a number"),
    ({"fx": 1e9, "cx": 320, "cy": 240}, r"fx: must be a number > 0 and <= 1e\+06, got 1000000000.0"),
    ({"fx": 1e5, "cx": 320, "cy": 240}, "field of view"),
    ({"fx": 10 ** 400, "cx": 320, "cy": 240}, "fx: must be a number > 0"),
    ({"matrix": [[500, 0, 320], [0, 500, 240], [0, 0, 0]]}, "matrix: must be a camera matrix"),
    ({"matrix": [[500, 0, 320], [0, 500, 240]]}, "matrix: must be 3x3 numbers, got shape"),
])
def test_file_values_are_checked_like_flags(tmp_path, doc, words):
    p = tmp_path / "k.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=words):
        resolve_intrinsics(IntrinsicsOptions(file=str(p)), 640, 480)


def test_deeply_nested_json_is_refused(tmp_path):
    p = tmp_path / "deep.json"
    p.write_text("[" * 200000 + "]" * 200000)
    with pytest.raises(InputError, match="nested too deeply"):
        resolve_intrinsics(IntrinsicsOptions(file=str(p)), 640, 480)


def _camera_info_yaml(path, width, height, k, d=(-0.017697, -0.00727, 0.005751, -0.000139, 0.0)):
    """A ROS camera_info YAML as ROS's camera_calibration writes it (calibrator.py, `lryaml`):
    no %YAML header, plain {rows, cols, data} maps, numbers as "%8f"."""
    def numbers(values):
        return ", ".join("%8f" % v for v in values)

    p = [k[0][0], 0, k[0][2], 0, 0, k[1][1], k[1][2], 0, 0, 0, 1, 0]
    path.write_text(f"image_width: {width}\nimage_height: {height}\ncamera_name: narrow_stereo\n"
                    f"camera_matrix:\n  rows: 3\n  cols: 3\n  data: [{numbers(sum(k, []))}]\n"
                    f"distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n"
                    f"  data: [{numbers(d)}]\nrectification_matrix:\n  rows: 3\n  cols: 3\n"
                    f"  data: [{numbers([1, 0, 0, 0, 1, 0, 0, 0, 1])}]\n"
                    f"projection_matrix:\n  rows: 3\n  cols: 4\n  data: [{numbers(p)}]\n")
    return path


K_1280 = [[1015.5, 0, 640.25], [0, 1012.75, 401.5], [0, 0, 1]]


def test_ros_camera_info_yaml_is_read(tmp_path):
    ros = _camera_info_yaml(tmp_path / "ost.yaml", 1280, 800, K_1280)
    k = resolve_intrinsics(IntrinsicsOptions(file=str(ros)), 1280, 800)
    assert (k.fx, k.fy, k.cx, k.cy, k.source) == (1015.5, 1012.75, 640.25, 401.5, "file:ost.yaml")


def test_a_file_for_another_resolution_is_scaled_with_a_warning(tmp_path):
    """The same picture at half the resolution: every intrinsic halves (the pinhole's pixels
    are twice as large), and the user is told, since a mode that crops the sensor would not."""
    from posecam.errors import PosecamWarning

    ros = _camera_info_yaml(tmp_path / "ost.yaml", 1280, 800, K_1280)
    with pytest.warns(PosecamWarning, match="calibrated for 1280x800 images, the input is 640x400: its "
                                            "intrinsics scaled by 0.5"):
        k = resolve_intrinsics(IntrinsicsOptions(file=str(ros)), 640, 400)
    assert (k.fx, k.fy, k.cx, k.cy) == (1015.5 / 2, 1012.75 / 2, 640.25 / 2, 401.5 / 2)


def _filestorage_yaml(path, width, height, k):
    import cv2
    import numpy as np

    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("image_width", width)
    storage.write("image_height", height)
    storage.write("camera_matrix", np.array(k, dtype=float))
    storage.write("distortion_coefficients", np.zeros((5, 1)))
    storage.release()
    return path


@pytest.mark.parametrize("kind", ["opencv", "ros"])
@pytest.mark.parametrize("size, words", [
    ((1080, 1920), "is 1080x1920; the input is turned a quarter from the calibration"),   # portrait video
    ((1920, 1440), "is 1920x1440; give intrinsics for this size"),                        # a 4:3 mode
    ((1000, 1080), "is 1000x1080; give intrinsics for this size"),       # cut at the side: not turned
])
def test_a_file_for_another_shape_is_refused(tmp_path, kind, size, words):
    k = [[1400.0, 0, 960.0], [0, 1400.0, 540.0], [0, 0, 1]]
    path = (_filestorage_yaml(tmp_path / "k.yml", 1920, 1080, k) if kind == "opencv"
            else _camera_info_yaml(tmp_path / "k.yaml", 1920, 1080, k))
    with pytest.raises(InputError, match=f"calibrated for 1920x1080 images, the input {words}"):
        resolve_intrinsics(IntrinsicsOptions(file=str(path)), *size)


def test_a_landscape_file_for_a_portrait_photo_is_refused_by_the_cli(tmp_path):
    from conftest import EXAMPLES, run_posecam

    landscape = _filestorage_yaml(tmp_path / "phone.yml", 1920, 1080, [[1400.0, 0, 960.0], [0, 1400.0, 540.0],
                                                                       [0, 0, 1]])
    out = tmp_path / "b.json"
    r = run_posecam("predict", EXAMPLES / "balance.jpg", "--intrinsics", landscape, "-o", out)   # 1080x1920
    assert r.returncode == 2 and "turned a quarter" in r.stderr and len(r.stderr.splitlines()) == 1, r.stderr
    assert not out.exists()
    portrait = _camera_info_yaml(tmp_path / "ost.yaml", 1080, 1920, [[1400.0, 0, 540.0], [0, 1400.0, 960.0],
                                                                     [0, 0, 1]])
    r = run_posecam("predict", EXAMPLES / "balance.jpg", "--intrinsics", portrait, "-o", out)
    assert r.returncode == 0, r.stderr
    written = json.loads(out.read_text())["inputs"][0]["intrinsics"]
    assert written.pop("distortion") == pytest.approx([-0.017697, -0.00727, 0.005751, -0.000139, 0.0])
    assert written == {"fx": 1400.0, "fy": 1400.0, "cx": 540.0, "cy": 960.0, "source": "file:ost.yaml"}


@pytest.mark.parametrize("edit, words", [
    (("rows: 3\n  cols: 3\n  data: [1015", "rows: 2\n  cols: 3\n  data: [1015"), "camera_matrix: must be a 3x3 matrix"),
    (("image_width: 1280", "image_width: wide"), "image_width: must be a whole number"),
    (("camera_matrix:", "camera_matrix: [\n"), r"not a readable OpenCV FileStorage or ROS camera_info YAML \(line 7: "),
])
def test_a_broken_camera_info_is_refused_in_one_line(tmp_path, edit, words):
    ros = _camera_info_yaml(tmp_path / "ost.yaml", 1280, 800, K_1280)
    ros.write_text(ros.read_text().replace(*edit, 1))
    with pytest.raises(InputError, match=words):
        resolve_intrinsics(IntrinsicsOptions(file=str(ros)), 1280, 800)


# ---- the lens's distortion, from every file that gives one ----

def test_distortion_is_read_from_every_intrinsics_source(tmp_path):
    import cv2
    import numpy as np

    wide = (-0.30, 0.10, 0.001, -0.002, 0.015)
    storage = cv2.FileStorage(str(tmp_path / "cam.yml"), cv2.FILE_STORAGE_WRITE)   # as calibrateCamera's sample
    storage.write("image_width", 1920)
    storage.write("image_height", 1080)
    storage.write("camera_matrix", np.array([[1400.0, 0, 960], [0, 1400, 540], [0, 0, 1]]))
    storage.write("distortion_coefficients", np.array([wide]).T)
    storage.release()
    as_json = tmp_path / "k.json"
    as_json.write_text(json.dumps({"fx": 1400, "cx": 960, "cy": 540, "dist": list(wide[:4])}))
    ros = _camera_info_yaml(tmp_path / "ost.yaml", 1920, 1080, [[1400.0, 0, 960.0], [0, 1400.0, 540.0], [0, 0, 1]],
                            d=wide)
    read = {name: resolve_intrinsics(IntrinsicsOptions(file=str(tmp_path / name)), 1920, 1080).distortion
            for name in ("cam.yml", "k.json", "ost.yaml")}
    assert read["cam.yml"] == pytest.approx(wide) and read["ost.yaml"] == pytest.approx(wide)
    assert read["k.json"] == pytest.approx(wide[:4])
    plain = _filestorage_yaml(tmp_path / "plain.yml", 1920, 1080, [[1400.0, 0, 960.0], [0, 1400.0, 540.0], [0, 0, 1]])
    assert resolve_intrinsics(IntrinsicsOptions(file=str(plain)), 1920, 1080).distortion == ()   # zeros: none


@pytest.mark.demo
def test_distortion_is_read_from_the_lab_calibration_in_both_formats():
    """Pose2Sim's demo calibration (examples/fetch_demo.py): the Qualisys file and the TOML made
    of it give cam01 the same distortion."""
    from conftest import EXAMPLES

    toml = resolve_intrinsics(IntrinsicsOptions(file=str(EXAMPLES / "demo/single/Calib.toml"), camera="cam01"),
                              1080, 1920)
    qca = resolve_intrinsics(IntrinsicsOptions(file=str(EXAMPLES / "demo/single/Calib.qca.txt"), camera="cam01"),
                             1080, 1920)
    assert toml.distortion == pytest.approx((-0.046183, 0.139983, 0.000608, 0.00069))
    assert qca.distortion == pytest.approx(toml.distortion)


def test_a_fisheye_or_odd_distortion_is_refused_in_one_line(tmp_path):
    k = [[1400.0, 0, 960.0], [0, 1400.0, 540.0], [0, 0, 1]]
    fisheye = _camera_info_yaml(tmp_path / "fish.yaml", 1920, 1080, k)
    fisheye.write_text(fisheye.read_text().replace("plumb_bob", "equidistant"))
    with pytest.raises(InputError, match="distortion_model: must be plumb_bob or rational_polynomial"):
        resolve_intrinsics(IntrinsicsOptions(file=str(fisheye)), 1920, 1080)
    odd = tmp_path / "odd.json"
    odd.write_text(json.dumps({"fx": 1400, "cx": 960, "cy": 540, "dist": [0.1, 0.2, 0.3]}))
    with pytest.raises(InputError, match="dist: must be 4 or 5 distortion coefficients"):
        resolve_intrinsics(IntrinsicsOptions(file=str(odd)), 1920, 1080)


def test_predict_lifts_through_the_lens_distortion_and_writes_it(tmp_path):
    """`predict --intrinsics cam.yml` used to give the same 3D to the millimetre whatever the
    file's k1: the distortion is undone before the lift, written in the JSON and read back,
    and the 2D keypoints stay the image's pixels."""
    import cv2
    import numpy as np

    from conftest import EXAMPLES, run_posecam
    from posecam.io.poses import read_poses

    roots, uvs = {}, {}
    for k1 in (0.0, -0.30):
        path = tmp_path / f"k{k1}.yml"
        storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
        storage.write("camera_matrix", np.array([[1400.0, 0, 540], [0, 1400, 960], [0, 0, 1]]))
        storage.write("distortion_coefficients", np.array([[k1, 0.0, 0.0, 0.0, 0.0]]))
        storage.release()
        out = tmp_path / f"k{k1}.json"
        r = run_posecam("predict", EXAMPLES / "balance.jpg", "--intrinsics", path, "-o", out)
        assert r.returncode == 0, r.stderr
        assert ("distortion -0.3 0 0 0 0" in " ".join(r.stdout.split())) == bool(k1), r.stdout   # the summary says it
        rec = read_poses(out)[0]
        assert rec.intrinsics.distortion == (pytest.approx((k1, 0.0, 0.0, 0.0, 0.0)) if k1 else ())
        person = rec.frames[0].people[0]
        roots[k1], uvs[k1] = person.root, person.keypoints_2d
    assert np.allclose(uvs[0.0], uvs[-0.30], atol=0.02)          # the image's pixels either way
    assert np.abs(roots[0.0] - roots[-0.30]).max() > 20            # mm: the lens moves the person


def test_values_in_messages_are_plain_numbers(tmp_path):
    """An OpenCV YAML with fx 0 answered `got np.float64(0.0)`: numbers as the user wrote them."""
    import numpy as np

    from conftest import EXAMPLES, run_posecam
    from posecam.geometry.camera import Intrinsics

    zero = _filestorage_yaml(tmp_path / "zero.yml", 1920, 1080, [[0.0, 0, 960.0], [0, 1400.0, 540.0], [0, 0, 1]])
    r = run_posecam("predict", EXAMPLES / "balance.jpg", "--intrinsics", zero, "-o", tmp_path / "out.json")
    assert r.returncode == 2 and r.stderr.strip().endswith("fx: must be a number > 0 and <= 1e+06, got 0.0"), r.stderr
    for bad, words in ((lambda: IntrinsicsOptions(fx=np.float64("nan")), "fx must be a finite number, got nan"),
                       (lambda: Intrinsics(np.float64(0.0), 1.0, 2.0, 3.0), "got fx=0, fy=1"),
                       (lambda: Intrinsics(np.float64("inf"), 1.0, 2.0, 3.0), "got inf, 1, 2, 3")):
        with pytest.raises(InputError) as caught:
            bad()
        assert words in str(caught.value) and "np." not in str(caught.value), caught.value
