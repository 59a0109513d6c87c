import tomllib

import cv2
import numpy as np
import pytest

from conftest import DATA
from posecam.errors import InputError
from posecam.geometry.camera import CameraCalibration, Intrinsics, Rig
from posecam.io.calibration import read_calibration, read_toml, write_toml
from posecam.io.intrinsics import IntrinsicsOptions, resolve_intrinsics
from synth_rig import make_rig, write_qca


def test_toml_round_trip(tmp_path):
    cams = make_rig()
    path = tmp_path / "calib.toml"
    write_toml(path, cams, {"frame": "world"})
    back = read_toml(path)
    assert [c.name for c in back] == [c.name for c in cams]
    for a, b in zip(cams, back):
        assert a.size == b.size
        np.testing.assert_allclose(a.rotation, b.rotation, atol=1e-9)
        np.testing.assert_allclose(a.translation, b.translation, atol=1e-6)
        np.testing.assert_allclose(a.intrinsics.matrix, b.intrinsics.matrix, atol=1e-9)


def test_bad_toml(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[cam]\nname = 'x'\nmatrix = [1, 2]\n")
    with pytest.raises(InputError):
        read_toml(path)
    with pytest.raises(InputError, match="does not exist"):
        read_toml(tmp_path / "missing.toml")


def test_qca_read_and_dispatch(tmp_path):
    cams = make_rig()
    qca = tmp_path / "Calib.qca.txt"
    write_qca(qca, cams)
    toml = tmp_path / "calib.toml"
    write_toml(toml, cams)
    for path in (qca, toml):
        rig = read_calibration(path)
        assert rig.names == sorted(c.name for c in cams) if path == qca else rig.names == [c.name for c in cams]
        for c in cams:
            back = rig.camera(c.name)
            np.testing.assert_allclose(back.rotation, c.rotation, atol=1e-9)
            np.testing.assert_allclose(back.translation, c.translation, atol=1e-6)
            np.testing.assert_allclose(back.intrinsics.matrix, c.intrinsics.matrix, atol=1e-6)
    with pytest.raises(InputError, match="does not exist"):
        read_calibration(tmp_path / "missing.qca.txt")


@pytest.mark.parametrize("size, expected", [
    ((1088, 1920), (1675.0, 1675.0, 530.0, 950.0)),        # as calibrated
    ((1080, 1920), (1675.0, 1675.0, 526.0, 950.0)),        # a few pixels narrower: centred crop
    ((544, 960), (837.5, 837.5, 265.0, 475.0)),            # half size: resized
])
def test_camera_for_crop_or_resize(size, expected):
    cam = CameraCalibration("cam01", (1088, 1920), Intrinsics(1675.0, 1675.0, 530.0, 950.0))
    k = Rig([cam]).camera_for("cam01", *size).intrinsics
    np.testing.assert_allclose((k.fx, k.fy, k.cx, k.cy), expected)


def test_camera_for_refuses_other_shapes():
    cam = CameraCalibration("cam01", (1088, 1920), Intrinsics(1675.0, 1675.0, 530.0, 950.0))
    with pytest.raises(InputError, match="calibrated for 1088x1920"):
        Rig([cam]).camera_for("cam01", 1920, 1080)


def test_match_by_name_then_sorted_order():
    cams = make_rig()                                      # front, right, back, left
    rig = Rig(cams)
    names = [c.name for c in cams][::-1]
    matched, note = rig.match(names, [c.size for c in cams][::-1])
    assert [c.name for c in matched] == names and note is None
    # names that say nothing: sorted cameras to sorted inputs, with one warning line
    videos = ["v4", "v2", "v1", "v3"]
    by_name = sorted(cams, key=lambda c: c.name)           # back, front, left, right
    sizes = {v: c.size for v, c in zip(sorted(videos), by_name)}
    matched, note = rig.match(videos, [sizes[v] for v in videos])
    assert "sorted order" in note and "\n" not in note
    for v, c in zip(videos, matched):
        np.testing.assert_allclose(c.rotation, by_name[sorted(videos).index(v)].rotation)
    with pytest.raises(InputError, match="do not match"):
        rig.match(["a", "b"], [(10, 10), (10, 10)])


def test_predict_and_fuse_take_the_same_intrinsics(tmp_path):
    """predict --intrinsics FILE --camera NAME and fuse --calibration FILE: one policy."""
    cams = make_rig()
    cams[1] = CameraCalibration(cams[1].name, (1088, 1920), cams[1].intrinsics, cams[1].rotation, cams[1].translation)
    qca = tmp_path / "Calib.qca.txt"
    write_qca(qca, cams)
    name = cams[1].name
    predict = resolve_intrinsics(IntrinsicsOptions(file=str(qca), camera=name), 1080, 1920)
    fuse = read_calibration(qca).match([name], [(1080, 1920)])[0][0].intrinsics
    assert (predict.fx, predict.fy, predict.cx, predict.cy) == (fuse.fx, fuse.fy, fuse.cx, fuse.cy)
    assert fuse.cx == pytest.approx(cams[1].intrinsics.cx - 4)


def test_the_lab_qualisys_file_reads_as_worked_out_by_hand():
    """Pose2Sim's shipped Calib.qca.txt, cam01, against numbers worked out by hand from its XML
    (not written by posecam): QTM stores focal length and principal point in 1/64 pixel, the
    field of view as inclusive pixel bounds, the camera's position in mm and its rotation with
    the camera's axes in the rows (r11 r12 r13 is the camera's x axis in the world), y up and z
    backwards; OpenCV's camera has y down and z forwards. Then, from the geometry alone: the
    four cameras look at the person standing near the world origin, and none is upside down."""
    assets = pytest.importorskip("export.assets", reason="the Pose2Sim wheel comes with the export extra")
    from posecam.io.calibration import read_qualisys

    cams = {c.name: c for c in read_qualisys(assets.pose2sim_demo_path("calibration/Calib.qca.txt"))}
    cam = cams["cam01"]
    assert cam.size == (1087 - 0 + 1, 1919 - 0 + 1)
    k = cam.intrinsics
    assert (k.fx, k.fy) == pytest.approx((107599.671875 / 64, 107588.828125 / 64))       # 1681.245, 1681.075
    assert (k.cx, k.cy) == pytest.approx((34110.316406 / 64, 60680.792969 / 64))         # 532.974, 948.137
    np.testing.assert_allclose(cam.distortion, [-0.046183, 0.139983, 0.000608, 0.00069])
    rows = np.array([[0.5536380477336265, 0.8046719867383512, 0.2144479094331626],      # r11 r12 r13
                     [-0.4345300743838753, 0.05946489349975602, 0.8986921279821063],    # r21 r22 r23
                     [0.7104002579937896, -0.5907342212870501, 0.3825762057979294]])    # r31 r32 r33
    np.testing.assert_allclose(cam.rotation, rows * [[1], [-1], [-1]], atol=1e-12)       # y, z flipped
    np.testing.assert_allclose(cam.centre, [1460.2323709212087, -1909.1590482454608, 1896.5058524092062], atol=1e-6)
    target = np.array([0.0, 0.0, 900.0])              # about the person's pelvis, 0.9 m above the lab floor
    for c in cams.values():
        to_target = (target - c.centre) / np.linalg.norm(target - c.centre)
        assert np.degrees(np.arccos(c.rotation[2] @ to_target)) < 20, c.name   # optical axis on the person
        assert -c.rotation[1][2] > 0.8, c.name                                  # image up is world up (z)
        uv = c.project(target[None])[0]
        assert 0 < uv[0] < c.size[0] and 0 < uv[1] < c.size[1], (c.name, uv)   # and in the picture
    cropped = {c.name: c for c in read_qualisys(assets.pose2sim_demo_path("calibration/Calib.qca.txt"),
                                                image_widths={"cam01": 1080})}["cam01"]
    assert cropped.size == (1080, 1920) and cropped.intrinsics.cx == pytest.approx(k.cx - 4)   # a centred crop


# ---- calibration files that other tools wrote (tests/data/SOURCE.md) ---------------------------

FOREIGN = ("pose2sim_Calib_scene.toml", "aniposelib_7cam_calibration.toml")


def _raw_cameras(name: str) -> list[dict]:
    """The camera tables of a calibration TOML as plain tomllib reads them, in file order."""
    return [t for key, t in tomllib.loads((DATA / name).read_text()).items() if key != "metadata"]


def _scene(tables: list[dict]) -> tuple[np.ndarray, float]:
    """The point nearest every camera's optical axis (least squares) and the cameras' median
    distance to it, from the raw values: x_cam = R(rvec) x + t, the axis the third row of R."""
    rotations = [cv2.Rodrigues(np.array(t["rotation"], float))[0] for t in tables]
    centres = np.array([-r.T @ np.array(t["translation"], float) for r, t in zip(rotations, tables)])
    across = np.array([np.eye(3) - np.outer(r[2], r[2]) for r in rotations])
    scene = np.linalg.solve(across.sum(axis=0), np.einsum("vij,vj->i", across, centres))
    return scene, float(np.median(np.linalg.norm(centres - scene, axis=1)))


@pytest.mark.parametrize("name", FOREIGN)
def test_foreign_calibration_projects_as_opencv_does(name):
    """Pose2Sim's own calibration of its demo's four cameras (checkerboard intrinsics, scene
    extrinsics) and a seven-camera rig adjusted by aniposelib, read by posecam: points around
    the scene the cameras look at project where OpenCV's projectPoints puts them with the
    file's raw values (read here by tomllib), distortion included, and come back to their
    rays through posecam's undistortion; the scene is in every camera's picture."""
    tables = _raw_cameras(name)
    rig = read_calibration(DATA / name)
    assert rig.names == [t["name"] for t in tables]
    scene, distance = _scene(tables)
    points = scene + np.random.default_rng(0).uniform(-0.15, 0.15, (40, 3)) * distance   # file units
    for t, cam in zip(tables, rig.cameras):
        rvec, tvec = np.array(t["rotation"], float), np.array(t["translation"], float)
        matrix, dist = np.array(t["matrix"], float), np.array(t["distortions"], float)
        assert cam.size == tuple(int(v) for v in t["size"])
        uv = cv2.projectPoints(points, rvec, tvec, matrix, dist)[0][:, 0]
        np.testing.assert_allclose(cam.project(points * 1000.0), uv, atol=1e-6)   # posecam: mm, the file: m
        local = points @ cv2.Rodrigues(rvec)[0].T + tvec
        np.testing.assert_allclose(cam.normalise(uv), local[:, :2] / local[:, 2:], atol=1e-5)
        u, v = cam.project(scene * 1000.0)
        assert 0 < u < cam.size[0] and 0 < v < cam.size[1], (cam.name, u, v)


def test_foreign_pose2sim_calibration_agrees_with_the_lab_qualisys_one():
    """The same four cameras calibrated twice, by two tools: Pose2Sim (its TOML) and the lab's
    Qualisys (the .qca.txt Pose2Sim ships), each read by its own posecam reader: the camera
    centres within 150 mm (measured 54-144), the rotations within 3 deg (0.9-2.7), the focal
    lengths within 1.5 % (0.6-0.9)."""
    assets = pytest.importorskip("export.assets", reason="the Pose2Sim wheel comes with the export extra")
    from posecam.io.calibration import read_qualisys

    lab = {c.name: c for c in read_qualisys(assets.pose2sim_demo_path("calibration/Calib.qca.txt"))}
    for cam in read_calibration(DATA / "pose2sim_Calib_scene.toml").cameras:
        other = lab[cam.name.removeprefix("int_").removesuffix("_img")]
        turn = other.rotation @ cam.rotation.T
        assert np.linalg.norm(other.centre - cam.centre) < 150, cam.name
        assert np.degrees(np.arccos((np.trace(turn) - 1) / 2)) < 3, cam.name
        assert abs(cam.intrinsics.fx / other.intrinsics.fx - 1) < 0.015, cam.name
