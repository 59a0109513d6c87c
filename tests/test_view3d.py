"""The 3D HTML view, rendered by a real headless browser (Debian's `chromium`): the page loads
from the file alone and the skeletons (and cameras) are drawn in their colours."""

import shutil
import subprocess
import tempfile

import cv2
import numpy as np
import pytest

from conftest import DATA, run_posecam
from posecam.geometry.camera import Rig
from posecam.results import Frame, Person, Recording
from posecam.skeleton import H36M_JOINTS
from posecam.viz.view3d import PALETTE, view3d_html, write_view3d
from synth_rig import make_rig, skeleton_motion

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="Debian package chromium is not installed")
CAMERA_GREY = (200, 204, 212)           # frustum colour in the page


def screenshot(page, tmp_path) -> np.ndarray:
    """RGB screenshot (1000x700) of an HTML file in headless Chromium, network off."""
    png = tmp_path / f"{page.stem}.png"
    with tempfile.TemporaryDirectory() as profile:
        r = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                            "--no-first-run", "--disable-background-networking", "--disable-component-update",
                            "--disable-sync", f"--user-data-dir={profile}", f"--screenshot={png}",
                            "--window-size=1000,700", page.resolve().as_uri()],
                           capture_output=True, text=True, timeout=120)
    assert png.exists(), r.stderr[-2000:]
    return cv2.cvtColor(cv2.imread(str(png)), cv2.COLOR_BGR2RGB)


def pixels_of(image: np.ndarray, rgb, tol: int = 12) -> int:
    return int((np.abs(image.astype(int) - np.array(rgb)).max(axis=-1) <= tol).sum())


def two_people_world(n: int = 20) -> tuple[Recording, Rig]:
    cams = make_rig()
    a, b = skeleton_motion(n, seed=0), skeleton_motion(n, seed=1, centre=(1500.0, 500.0))
    frames = [Frame(i, i / 30, [Person(pid, 1.0, np.zeros(4), np.zeros((17, 2)), pose[i], np.ones(17))
                                for pid, pose in ((3, a), (8, b))]) for i in range(n)]
    return Recording("fused", 1920, 1080, None, H36M_JOINTS, frames, fps=30.0, frame_of_reference="world"), Rig(cams)


def test_page_is_self_contained():
    rec, rig = two_people_world()
    page = view3d_html(rec, rig)
    assert "http://" not in page and "https://" not in page and "src=" not in page and "@import" not in page
    assert page.count("<script") == 1


@needs_chromium
def test_fused_view_draws_both_people_and_the_cameras(tmp_path):
    rec, rig = two_people_world()
    write_view3d(tmp_path / "fused.html", rec, rig)
    image = screenshot(tmp_path / "fused.html", tmp_path)
    assert image.shape == (700, 1000, 3)
    assert pixels_of(image, PALETTE[0]) > 150 and pixels_of(image, PALETTE[1]) > 150    # ids 3 and 8
    assert pixels_of(image, CAMERA_GREY, tol=20) > 100                                  # the frustums


@needs_chromium
def test_predict_viz3d_of_a_real_clip(tmp_path):
    """`posecam predict --viz3d` on a real clip: camera coordinates, the one person kept drawn
    (--max-people 1 keeps the balancing adult, the tallest; the bystander is left out)."""
    page = tmp_path / "clip.html"
    r = run_posecam("predict", DATA / "balance_cam01_30f.mp4", "--max-people", "1", "--viz3d", page)
    assert r.returncode == 0, r.stderr
    image = screenshot(page, tmp_path)
    assert pixels_of(image, PALETTE[0]) > 150
    assert pixels_of(image, PALETTE[1]) == 0                  # one person, one colour


def test_viz3d_refuses_several_inputs_and_other_suffixes(tmp_path):
    r = run_posecam("predict", DATA / "messi5.jpg", DATA / "fruits.jpg", "--viz3d", tmp_path / "v.html")
    assert r.returncode == 2 and r.stderr.startswith("posecam: error: --viz3d holds one input")
    r = run_posecam("predict", DATA / "messi5.jpg", "--viz3d", tmp_path / "v.png")
    assert r.returncode == 2 and "--viz3d must end in .html" in r.stderr
    r = run_posecam("predict", DATA / "messi5.jpg", "--out-dir", tmp_path / "many", "--viz3d", tmp_path / "v.html")
    assert r.returncode == 2 and "--viz3d" in r.stderr and r.stderr.startswith("posecam: error:")
    assert not list(tmp_path.iterdir())


def test_rendered_labels_are_clear_of_the_lines():
    """--viz3d FILE.mp4: in every frame no camera name or person id sits on a frustum's or a
    skeleton's line (each line sampled every few pixels), and no two labels overlap."""
    from posecam.viz.render3d import SIZE, _OrbitCamera, frame_labels
    from posecam.viz.view3d import scene

    rec, rig = two_people_world()
    data = scene(rec, rig)
    view = _OrbitCamera(data, SIZE)
    edges = [(c["c"], c["corners"][i]) for c in data["cameras"] for i in range(4)]
    edges += [(c["corners"][i], c["corners"][(i + 1) % 4]) for c in data["cameras"] for i in range(4)]
    edges += [(c["corners"][k], c["up"]) for c in data["cameras"] for k in (0, 1)]
    for f in data["frames"]:
        lines = edges + [(p["p"][a], p["p"][b]) for p in f["people"] for a, b in data["bones"]]
        ends = np.array([[view.project(a), view.project(b)] for a, b in lines], float)      # (L, 2, 2) px
        samples = (ends[:, :1] + np.linspace(0, 1, 60)[None, :, None] * (ends[:, 1:] - ends[:, :1])).reshape(-1, 2)
        boxes = [box for _, box, _ in frame_labels(data, view, f)]
        assert len(boxes) == len(f["people"]) + len(data["cameras"])
        for i, (x, y, w, h) in enumerate(boxes):
            inside = (samples[:, 0] > x) & (samples[:, 0] < x + w) & (samples[:, 1] > y) & (samples[:, 1] < y + h)
            assert not inside.any(), (f["i"], i, (x, y, w, h))
            for a, b, c, d in boxes[:i]:
                assert x + w <= a or a + c <= x or y + h <= b or b + d <= y
