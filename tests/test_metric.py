"""posecam.scale and posecam.geometry.floor: heights, one scale per track, the floor.

The scenes are built here: people of known heights standing and walking on a floor seen by a
tilted camera, whose "pose model" output is what BlazePose gives, an adult-sized skeleton put on
the 2D keypoints, i.e. the true pose scaled about the camera centre by adult size / true size."""

import json

import numpy as np
import pytest

from conftest import DATA, run_posecam
from posecam.geometry.camera import DEFAULT_FOCAL_SD, Intrinsics, project
from posecam.geometry.lift import solve_root_translation
from posecam.scale.heights import Heights
from posecam.io.poses import read_poses, write_poses
from posecam.scale.metric import MODEL_STATURE, MetricOptions, MetricStage, _Sample, scale_recording
from posecam.scale.stature import CHAIN_OF_STATURE, stature
from posecam.results import Frame, Person, Recording
from posecam.skeleton import H36M_JOINTS

K = Intrinsics(1400.0, 1400.0, 960.0, 540.0)
CAMERA_HEIGHT = 2000.0      # mm above the floor
TILT = np.radians(12.0)     # the camera looks down this much
ADULT = 1700.0              # mm: the pose model's skeleton


def standing(h: float) -> np.ndarray:
    """A standing 17-joint pose of stature h (mm), feet on y = 0, y down, facing the camera."""
    leg_x, sh_x = 0.09 * h, 0.13 * h
    head = 0.53 * h + 0.288 * h + (CHAIN_OF_STATURE - 0.779) * h       # the chain spans CHAIN_OF_STATURE
    y = {"ankle": -0.039 * h, "knee": -0.285 * h, "hip": -0.531 * h, "thorax": -0.819 * h}
    pts = {
        "pelvis": (0, y["hip"]), "r_hip": (-leg_x, y["hip"]), "r_knee": (-leg_x, y["knee"]), "r_ankle": (-leg_x, y["ankle"]),
        "l_hip": (leg_x, y["hip"]), "l_knee": (leg_x, y["knee"]), "l_ankle": (leg_x, y["ankle"]),
        "spine": (0, -0.67 * h), "thorax": (0, y["thorax"]), "nose": (0, -head + 0.01 * h), "head": (0, -head),
        "l_shoulder": (sh_x, y["thorax"]), "l_elbow": (sh_x + 0.02 * h, -0.63 * h), "l_wrist": (sh_x + 0.03 * h, -0.48 * h),
        "r_shoulder": (-sh_x, y["thorax"]), "r_elbow": (-sh_x - 0.02 * h, -0.63 * h), "r_wrist": (-sh_x - 0.03 * h, -0.48 * h),
    }
    return np.array([[pts[j][0], pts[j][1], 0.0] for j in H36M_JOINTS])


def to_camera(world: np.ndarray, height: float = CAMERA_HEIGHT) -> np.ndarray:
    """World (x right, y down, z forward, floor at y = 0 below the camera) -> tilted camera."""
    c, s = np.cos(TILT), np.sin(TILT)
    r = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    return (world + [0.0, height, 0.0]) @ r.T


def scene(heights_mm: dict[int, float], frames: int = 60, noise: float = 0.0, seed: int = 0, climb: float = 0.0):
    """A recording of people walking on the floor, as the pose model sees them (adult-sized),
    and the true camera-space poses by (frame, id). `climb`: the camera rises this much (mm) a
    frame; `noise`: the relative frame-to-frame noise of the model skeleton's size."""
    rng = np.random.default_rng(seed)
    rec = Recording("scene.mp4", 1920, 1080, K, H36M_JOINTS, fps=30.0)
    truth = {}
    for i in range(frames):
        people = []
        for pid, h in heights_mm.items():
            where = np.array([-1500.0 + 1000 * pid + 30 * i * (-1) ** pid, 0.0, 3500.0 + 1500 * pid + 40 * i])
            true = to_camera(standing(h) + where, CAMERA_HEIGHT + climb * i)
            model = true * (ADULT / h) * (1 + noise * rng.standard_normal())
            uv = project(true, K)
            people.append(Person(pid, 0.9, np.r_[uv.min(0), uv.max(0)], uv, model, np.full(17, 0.9)))
            truth[(i, pid)] = true
        rec.frames.append(Frame(i, i / 30.0, people))
    return rec, truth


def test_a_scaled_skeleton_is_placed_at_the_scaled_position():
    """The fact the stage is built on: the root solve is linear and homogeneous in the skeleton."""
    rng = np.random.default_rng(3)
    rel = rng.normal(0, 300, (17, 3))
    uv = rng.uniform(200, 900, (17, 2))
    w = rng.uniform(0.3, 1, 17)
    t = solve_root_translation(rel, uv, w, K)
    for s in (0.7, 1.3):
        assert np.allclose(solve_root_translation(s * rel, uv, w, K), s * t)
        assert np.allclose(project(s * (rel + t), K), project(rel + t, K))


def test_stature_of_a_skeleton_whatever_its_pose():
    pose = standing(1650.0)
    assert stature(pose, np.ones(17), H36M_JOINTS) == pytest.approx(1650.0, rel=0.01)
    bent = pose.copy()
    bent[[2, 5], 2] -= 300.0                                                    # knees forward ...
    assert stature(bent, np.ones(17), H36M_JOINTS) > 1650.0                     # bones measured as they are
    conf = np.ones(17)
    conf[3] = 0.1
    assert np.isnan(stature(pose, conf, H36M_JOINTS))


def test_the_floor_puts_people_of_different_sizes_at_their_depths():
    rec, truth = scene({0: 1750.0, 1: 1200.0})
    out = scale_recording(rec)
    assert out.floor is not None
    assert out.floor.distance == pytest.approx(CAMERA_HEIGHT, rel=0.03)
    assert np.degrees(np.arccos(out.floor.normal @ [0, np.cos(TILT), np.sin(TILT)])) < 2
    before = np.median([abs(p.root[2] / truth[(f.index, p.id)][0, 2] - 1) for f in rec.frames for p in f.people if p.id == 1])
    assert before > 0.3                                                          # the child, placed as an adult
    for f in out.frames:
        for p in f.people:
            assert p.height_source == "floor"
            assert abs(p.root[2] - truth[(f.index, p.id)][0, 2]) < 0.04 * truth[(f.index, p.id)][0, 2]
    child = out.frames[-1].people[1]
    assert child.height_estimated == pytest.approx(1.2 * ADULT / 1750, rel=0.04)  # the adult keeps the model's size
    assert 0 < child.height_sd < 0.2 and child.depth_sd > 0


def test_given_heights_by_rank_and_by_id():
    rec, truth = scene({0: 1750.0, 1: 1200.0}, frames=20)
    ranked = scale_recording(rec, MetricOptions(heights=Heights.parse(["1.75,1.20"])))   # the floor ranks them
    p0, p1 = ranked.frames[5].people
    assert (p0.height_source, p1.height_source) == ("given, rank 1", "given, rank 2")
    assert (p0.height, p1.height) == pytest.approx((1.75, 1.20))
    by_id = scale_recording(rec, MetricOptions(heights=Heights.parse(["1=1.20"]), floor=False))
    p0, p1 = by_id.frames[5].people
    assert (p0.height_source, p1.height_source, p1.height) == ("model", "given", pytest.approx(1.20))
    assert abs(p1.root[2] - truth[(5, 1)][0, 2]) < 0.02 * truth[(5, 1)][0, 2]    # the given height places the child


def test_a_list_of_heights_for_people_of_one_size_is_a_note():
    """Two people 1 cm apart and a list of two heights: the floor cannot tell who is taller, and
    the stage says so (with the ranks it gave); 55 cm apart it says nothing."""
    for heights_mm, doubtful in (({0: 1750.0, 1: 1740.0}, True), ({0: 1750.0, 1: 1200.0}, False)):
        rec, _ = scene(heights_mm, frames=20)
        stage = MetricStage(rec, MetricOptions(heights=Heights.parse(["1.75,1.20"])))
        for f in rec.frames:
            stage.push(f)
        stage.flush()
        notes = [n for n in stage.notes if "too close in height" in n]
        assert len(notes) == int(doubtful), stage.notes


def test_each_track_keeps_one_size_across_frames():
    rec, _ = scene({0: 1700.0}, frames=40, noise=0.05, seed=4)
    raw = np.array([stature(f.people[0].keypoints_3d, f.people[0].confidence, H36M_JOINTS) for f in rec.frames])
    out = scale_recording(rec, MetricOptions(floor=False))
    kept = np.array([stature(f.people[0].keypoints_3d, f.people[0].confidence, H36M_JOINTS) for f in out.frames])
    assert raw.std() / raw.mean() > 0.03 and kept.std() / kept.mean() < 1e-6


def test_tracks_with_nothing_else_to_scale_them_get_the_pose_models_size():
    """BlazePose's skeleton has one size whoever the person: a track's own size is its error."""
    import dataclasses

    rec, _ = scene({0: 1700.0, 1: 1700.0}, frames=20)
    for f in rec.frames:                            # the model sized the two people apart
        f.people[0].keypoints_3d *= 1630.0 / ADULT
        f.people[1].keypoints_3d *= 1690.0 / ADULT
    full = scale_recording(dataclasses.replace(rec, model="blazepose-full"), MetricOptions(floor=False))
    unknown = scale_recording(rec, MetricOptions(floor=False))
    size = MODEL_STATURE["blazepose-full"]
    for f, g, h in zip(rec.frames, full.frames, unknown.frames):
        for p, q, r, own in zip(f.people, g.people, h.people, (1.63, 1.69)):
            assert (q.height_source, q.height, q.height_estimated) == ("model", pytest.approx(size), pytest.approx(size))
            assert q.root[2] == pytest.approx(p.root[2] * size / own, rel=1e-3)        # scaled about the camera
            assert np.allclose(q.keypoints_2d, p.keypoints_2d)
            assert r.height == pytest.approx(own, rel=1e-3) and r.root[2] == pytest.approx(p.root[2], rel=1e-3)


def test_someone_never_seen_whole_keeps_the_models_size_and_its_spread():
    """A person whose legs are never in view (framed from the waist up) has no stature to
    measure: the skeleton the pose model gave them stays as it is, at the model's size, its
    depth spread by that size's uncertainty (and an assumed lens's); a height given for them
    scales it about the camera. Someone seen whole beside them is measured as before."""
    import dataclasses

    from posecam.geometry.camera import DEFAULT_FOCAL_SD
    from posecam.scale.policy import SCALE

    rec, _ = scene({0: 1700.0, 1: 1700.0}, frames=20)
    rec = dataclasses.replace(rec, model="blazepose-full")
    legs = [H36M_JOINTS.index(j) for j in ("r_knee", "r_ankle", "l_knee", "l_ankle")]
    for f in rec.frames:
        f.people[1].confidence[legs] = 0.05
    size = MODEL_STATURE["blazepose-full"]
    cases = [(K, Heights(), 1.0, "model", SCALE.model_sd),
             (dataclasses.replace(K, source="default"), Heights(), 1.0, "model", np.hypot(SCALE.model_sd, DEFAULT_FOCAL_SD)),
             (K, Heights.parse(["1=1.50"]), 1.50 / size, "given", SCALE.given_sd)]
    for lens, heights, scale, source, spread in cases:
        out = scale_recording(dataclasses.replace(rec, intrinsics=lens), MetricOptions(floor=False, heights=heights))
        for f, g in zip(rec.frames, out.frames):
            whole, cut = g.people
            assert whole.height_source == "model" and whole.depth_sd > 0
            assert cut.height_source == source and cut.height == pytest.approx(size * scale)
            assert np.allclose(cut.keypoints_3d, f.people[1].keypoints_3d * scale)
            assert cut.depth_sd == pytest.approx(spread * cut.root[2], rel=1e-6)


def test_a_track_measured_far_from_the_models_size_is_left_unmeasured():
    """Frames whose legs the pose model folded to the knees (a man cut there; half of his
    frames) measure him 28 % short; scaled up to the model's size they would put him that much
    too far. The model gives everyone one size, so such a track is left as the model gave it."""
    import dataclasses

    rec, _ = scene({0: 1700.0}, frames=20)
    rec = dataclasses.replace(rec, model="blazepose-full")
    legs = [H36M_JOINTS.index(j) for j in ("r_knee", "r_ankle", "l_knee", "l_ankle")]
    folded = [H36M_JOINTS.index(j) for j in ("r_ankle", "l_ankle")]
    for f in rec.frames:
        p = f.people[0]
        if f.index < 10:                            # legs folded up to the knees, confidently
            knees = [H36M_JOINTS.index("r_knee"), H36M_JOINTS.index("l_knee")]
            p.keypoints_3d[folded], p.keypoints_2d[folded] = p.keypoints_3d[knees], p.keypoints_2d[knees]
        else:
            p.confidence[legs] = 0.05
    out = scale_recording(rec, MetricOptions(floor=False))
    for f, g in zip(rec.frames, out.frames):
        assert np.allclose(g.people[0].keypoints_3d, f.people[0].keypoints_3d)


def test_a_track_measured_on_a_few_of_its_frames_is_left_unmeasured_and_off_the_floor():
    """Two people on a floor; the second's legs are out of view but on 6 frames of 60, where the
    pose model put the ankles 30 % of the way up the shins (folded into view: 9 % short, within
    the model's size). Measured there, the floor would place them 7 % off; measured on under a
    quarter of their frames, they are left as the pose model gave them (within 1 %)."""
    import dataclasses

    rec, truth = scene({0: 1700.0, 1: 1700.0})
    rec = dataclasses.replace(rec, model="blazepose-full")
    legs = [H36M_JOINTS.index(j) for j in ("r_knee", "r_ankle", "l_knee", "l_ankle")]
    knees = [H36M_JOINTS.index(j) for j in ("r_knee", "l_knee")]
    ankles = [H36M_JOINTS.index(j) for j in ("r_ankle", "l_ankle")]
    for f in rec.frames:
        p = f.people[1]
        if f.index in (10, 20, 30, 40, 50, 55):
            for points in (p.keypoints_3d, p.keypoints_2d):
                points[ankles] += 0.3 * (points[knees] - points[ankles])
        else:
            p.confidence[legs] = 0.05
    out = scale_recording(rec)
    assert out.floor is not None and out.floor.distance == pytest.approx(CAMERA_HEIGHT, rel=0.03)
    for f, g in zip(rec.frames, out.frames):
        cut = g.people[1]
        assert cut.height_source == "model"
        assert np.allclose(cut.keypoints_3d, f.people[1].keypoints_3d, atol=5.0)   # (placed on its core joints)
        assert abs(cut.root[2] / truth[(f.index, 1)][0, 2] - 1) < 0.01


@pytest.mark.parametrize("why, make", [
    ("too few foot contacts", lambda: scene({0: 1700.0}, frames=1)[0]),
    ("a moving camera", lambda: scene({0: 1700.0, 1: 1600.0}, frames=60, climb=25.0)[0]),   # a moving camera
])
def test_the_floor_is_refused_when_the_feet_do_not_support_it(why, make):
    stage = MetricStage(make())
    for f in stage.rec.frames:
        stage.push(f)
    stage.flush()
    assert stage.floor is None and why in stage.floor_refused


def test_nobody_upright_gives_no_floor():
    rec, _ = scene({0: 1700.0}, frames=30)
    for f in rec.frames:
        f.people[0].keypoints_3d[[2, 5], 2] -= 400.0         # knees bent forward in every frame
    stage = MetricStage(dataclass_copy(rec))
    for f in rec.frames:
        stage.push(f)
    stage.flush()
    assert stage.floor is None and "upright" in stage.floor_refused


def dataclass_copy(rec):
    import dataclasses

    return dataclasses.replace(rec, frames=[])


def test_the_stage_streams_in_bounded_memory():
    sample = _Sample(size=8)
    for i in range(1000):
        sample.add(i)
    assert len(sample.rows) <= 8 and sample.rows[0] == 0 and sample.rows[-1] > 800     # spread over the stream
    rec, _ = scene({0: 1750.0, 1: 1200.0}, frames=60)
    stage = MetricStage(dataclass_copy(rec), MetricOptions(delay=10))
    out = []
    for i, f in enumerate(rec.frames):
        out += stage.push(f)
        assert len(out) == max(0, i + 1 - 10)
    out += stage.flush()
    assert [f.index for f in out] == list(range(60))


def test_heights_and_floor_round_trip_through_json(tmp_path):
    rec, _ = scene({0: 1750.0, 1: 1200.0}, frames=30)
    out = scale_recording(rec)
    write_poses(tmp_path / "p.json", [out])
    doc = json.loads((tmp_path / "p.json").read_text())
    assert set(doc["inputs"][0]["floor"]) == {"normal", "distance", "spread", "contacts", "tracks"}
    assert {"height", "height_source", "height_estimated", "height_sd", "depth_sd"} <= set(doc["inputs"][0]["frames"][0]["people"][0])
    back = read_poses(tmp_path / "p.json")[0]
    assert back.floor.distance == pytest.approx(out.floor.distance, abs=0.1)
    p, q = back.frames[3].people[1], out.frames[3].people[1]
    assert (p.height_source, p.height) == (q.height_source, round(q.height, 3))
    for person in doc["inputs"][0]["frames"][0]["people"]:            # a file from before: no such fields
        for key in ("height", "height_source", "height_estimated", "height_sd", "depth_sd"):
            person.pop(key)
    del doc["inputs"][0]["floor"]
    (tmp_path / "old.json").write_text(json.dumps(doc))
    old = read_poses(tmp_path / "old.json")[0]
    assert old.floor is None and old.frames[0].people[0].height_source == "" and np.isnan(old.frames[0].people[0].height)


def test_the_3d_view_draws_the_fitted_floor():
    from posecam.viz.view3d import scene as page_data

    rec, _ = scene({0: 1750.0, 1: 1200.0}, frames=30)
    assert page_data(rec)["plane"] == []                           # no plane fitted: the level grid
    out = scale_recording(rec)
    lines = np.array(page_data(out)["plane"])                      # (L, 2, 3) display axes (y up), m
    assert len(lines) >= 6
    camera = lines.reshape(-1, 3) * 1000.0 * [1, -1, -1]
    assert np.allclose(out.floor.height_of(camera), 0.0, atol=5.0)
    feet = np.array([p.keypoints_3d[[3, 6]] for f in out.frames for p in f.people]).reshape(-1, 3)
    assert np.all(np.abs(out.floor.height_of(feet) - 0.039 * 1750) < 60)   # the feet stand on it


def test_predict_records_the_given_height(tmp_path):
    out = tmp_path / "m.json"
    r = run_posecam("predict", DATA / "messi5.jpg", "--height", "1.70", "-o", out)
    assert r.returncode == 0, r.stderr
    plain = tmp_path / "plain.json"
    assert run_posecam("predict", DATA / "messi5.jpg", "-o", plain).returncode == 0
    (p,) = json.loads(out.read_text())["inputs"][0]["frames"][0]["people"]
    (q,) = json.loads(plain.read_text())["inputs"][0]["frames"][0]["people"]
    assert (p["height"], p["height_source"], q["height_source"]) == (1.70, "given", "model")
    assert q["height"] == pytest.approx(MODEL_STATURE["blazepose-full"], abs=0.001)     # the model's one size
    ratio = 1.70 / q["height"]
    assert p["root"][2] == pytest.approx(q["root"][2] * ratio, rel=0.002)       # scaled about the camera centre
    assert np.allclose(p["keypoints_2d"], q["keypoints_2d"])


def test_predict_refuses_a_height_in_centimetres():
    r = run_posecam("predict", DATA / "messi5.jpg", "--height", "172")
    assert r.returncode == 2 and "centimetres" in r.stderr and "Traceback" not in r.stderr


def walkers(n_tracks: int = 6, frames: int = 40, tilt: float = TILT, seed: int = 7) -> dict:
    """Upright people of different heights walking across the floor at different places:
    {(track, frame): true camera-space pose}, seen by a camera tilted down by `tilt`."""
    global TILT
    rng = np.random.default_rng(seed)
    saved, TILT, out = TILT, tilt, {}
    try:
        for t in range(n_tracks):
            start = np.array([rng.uniform(-3000, 3000), 0.0, rng.uniform(4000, 9000)])
            step, h = rng.normal(0, 60, 3) * [1, 0, 1], rng.uniform(1500, 1900)
            for i in range(frames):
                out[(t, i)] = to_camera(standing(h) + start + i * step)
    finally:
        TILT = saved
    return out


def heads_and_feet(poses: dict, seed: int = 0):
    rng = np.random.default_rng(seed)
    uv = {key: project(pose, K) + rng.normal(0, 1.0, (17, 2)) for key, pose in poses.items()}
    return (np.array([p[10] for p in uv.values()]), np.array([p[[3, 6]].mean(axis=0) for p in uv.values()]),
            np.array([key[0] for key in uv]))


def test_the_lens_from_people_walking_on_a_floor():
    from posecam.scale.lens import focal_from_people

    heads, feet, tracks = heads_and_feet(walkers())
    fit = focal_from_people(heads, feet, tracks, np.array([K.cx, K.cy]), 1080)
    assert fit.focal == pytest.approx(K.fx, rel=0.05) and 0 < fit.sd < 0.1 * K.fx, fit
    one_place = focal_from_people(heads[:30], feet[:30] * [0, 1] + [900, 0], tracks[:30], np.array([K.cx, K.cy]), 1080)
    assert one_place.focal is None and "one place" in one_place.reason
    level = focal_from_people(*heads_and_feet(walkers(tilt=0.0)), np.array([K.cx, K.cy]), 1080)
    assert level.focal is None and "parallel" in level.reason


def _through_the_default_lens(frames: int) -> tuple[Recording, dict]:
    """Walkers as the pose model gives them with the default lens (700 px, K's is 1400): the
    right shape, placed through the wrong lens; and the true poses."""
    poses = walkers(frames=frames)
    default = Intrinsics(700.0, 700.0, K.cx, K.cy, "default")
    rec = Recording("walk.mp4", 1920, 1080, default, H36M_JOINTS, fps=30.0, frames=[Frame(i, i / 30) for i in range(frames)])
    for (t, i), true in poses.items():
        uv, rel = project(true, K), true - true[0]
        xyz = rel + solve_root_translation(rel, uv, np.ones(17), default)
        rec.frames[i].people.append(Person(t, 0.9, np.r_[uv.min(0), uv.max(0)], uv, xyz, np.full(17, 0.9)))
    return rec, poses


def test_the_stage_takes_the_lens_from_the_people_in_place_of_the_default():
    rec, poses = _through_the_default_lens(30)
    assert np.median([p.root[2] / poses[(p.id, f.index)][0, 2] for f in rec.frames for p in f.people]) < 0.6
    out = scale_recording(rec, MetricOptions(floor=False))
    assert out.intrinsics.source.startswith("people") and out.intrinsics.fx == pytest.approx(K.fx, rel=0.05)
    ratio = [p.root[2] / poses[(p.id, f.index)][0, 2] for f in out.frames for p in f.people]
    assert np.median(ratio) == pytest.approx(1.0, abs=0.05)
    # the depth's spread: the people's lens's, far under the default lens's 30 % (kept, 50 % off here)
    kept = scale_recording(rec, MetricOptions(floor=False, lens=False))
    spread = {name: np.median([p.depth_sd / p.root[2] for f in r.frames for p in f.people])
              for name, r in (("people", out), ("default", kept))}
    assert spread["people"] < 0.15 < DEFAULT_FOCAL_SD < spread["default"], spread


def test_frames_after_the_lens_is_decided_are_placed_through_it_too():
    """The lens is decided on the first `delay` frames; the frames that come after are solved
    through it as they come: every frame's people at their depth, not only the first ones, and
    those whose legs and shoulders are hidden from frame 30 (under MIN_CONFIDENCE: the hips
    alone are too few to place the root again) too."""
    rec, poses = _through_the_default_lens(60)
    hidden = [H36M_JOINTS.index(j) for j in ("r_knee", "r_ankle", "l_knee", "l_ankle", "r_shoulder", "l_shoulder")]
    for f in rec.frames[30:]:
        for p in f.people:
            p.confidence[hidden] = 0.3
    out = scale_recording(rec, MetricOptions(floor=False, delay=15))
    assert out.intrinsics.source.startswith("people")
    per_frame = [np.median([p.root[2] / poses[(p.id, f.index)][0, 2] for p in f.people]) for f in out.frames]
    assert len(per_frame) == 60 and np.abs(np.array(per_frame) - 1).max() < 0.02, np.round(per_frame, 2)


def test_the_default_lens_is_in_the_depth_spread(tmp_path):
    """Pose2Sim's cam01, 30 frames (540x960), no lens given: the 28 mm-equivalent default lens
    (713 px) is 15 % short of the lab's (834 px at this size: examples/cam01_intrinsics.json, for
    1088x1920, halved), so every depth comes out 15 % near; each frame's depth_sd covers that
    within two of it. With the lab's lens given, the spread has no lens in it: under half."""
    runs = {}
    for name, lens in (("default", ()), ("lab", ("--fx", "834.4", "--fy", "834.3", "--cx", "264.5", "--cy", "470.6"))):
        out = tmp_path / f"{name}.json"
        run = run_posecam("predict", DATA / "balance_cam01_30f.mp4", *lens, "--no-smooth", "-o", out)
        assert run.returncode == 0, run.stderr
        rec = read_poses(out)[0]
        runs[name] = {f.index: max(f.people, key=lambda p: p.bbox[3] - p.bbox[1]) for f in rec.frames if f.people}
    frames = sorted(set(runs["default"]) & set(runs["lab"]))
    assert len(frames) >= 25
    default, lab = ([runs[n][i] for i in frames] for n in ("default", "lab"))
    near = np.array([d.root[2] / g.root[2] for d, g in zip(default, lab)])
    assert 0.80 < np.median(near) < 0.90, np.median(near)           # the default lens's 15 %
    assert all(abs(d.root[2] - g.root[2]) <= 2 * d.depth_sd for d, g in zip(default, lab))
    assert all(g.depth_sd / g.root[2] < 0.5 * d.depth_sd / d.root[2] for d, g in zip(default, lab))


def test_a_floor_that_would_make_someone_a_toddler_is_refused(tmp_path):
    """Pose2Sim's cam01, 30 frames: the man balances on a board (his feet off the ground) and a
    bystander stands at the left border. Their feet fit a plane that made the man 0.56 m tall
    (0.85 m with the lab's lens) and put him at 1 m instead of about 3 m; no such floor is used."""
    out = tmp_path / "poses.json"
    run = run_posecam("predict", DATA / "balance_cam01_30f.mp4", "-o", out)
    assert run.returncode == 0 and "no floor: the feet's plane would make person" in run.stderr, run.stderr
    assert "an adult's (1.68 m): a child or anyone far from it is placed too far" in run.stderr, run.stderr
    rec = read_poses(out)[0]
    people = [p for f in rec.frames for p in f.people]
    assert {p.height_source for p in people} == {"model"}
    subject = max(rec.frames[0].people, key=lambda p: p.bbox[3] - p.bbox[1])
    assert 2500 < subject.root[2] < 3500     # the board stands about 3 m from cam01 (the default lens)


def test_the_roots_depth_does_not_follow_arms_misplaced_in_depth():
    """Jumping jacks on the spot: a person standing 4 m away, whose arms the pose model puts
    from 300 mm in front of the body to 300 mm behind it frame by frame (the 2D keypoints, the
    truth, stay where they are), each pose placed on all its keypoints as the lift places it
    (the root's depth then swings with the arms, by 57 mm). After the metric stage it holds
    within 5 mm of the truth on every frame."""
    rec = Recording("jacks.mp4", 1920, 1080, K, H36M_JOINTS, fps=30.0)
    true = to_camera(standing(ADULT) + [0.0, 0.0, 4000.0])
    uv = project(true, K)
    arms = np.array(["elbow" in j or "wrist" in j for j in H36M_JOINTS])
    swings = []
    for i in range(40):
        model = true - true[0]
        model[arms, 2] += 300.0 * np.sin(i / 3)            # the arms misplaced in depth
        placed = model + solve_root_translation(model, uv, np.full(17, 0.9), K)
        swings.append(placed[0, 2])
        rec.frames.append(Frame(i, i / 30.0, [Person(0, 0.9, np.r_[uv.min(0), uv.max(0)], uv, placed, np.full(17, 0.9))]))
    assert np.ptp(swings) > 50.0                            # as placed, the depth swings with the arms
    depths = np.array([f.people[0].root[2] for f in scale_recording(rec, MetricOptions(floor=False)).frames])
    assert np.abs(depths - true[0, 2]).max() < 5.0


def test_the_trunk_alone_places_someone_whose_legs_are_out_of_view():
    """The same jumping jacks framed from the waist up (knees and ankles not confident, so
    never measured: the pose model's skeleton as it is): the root is placed on the trunk's four
    corners, shoulders and hips, and holds within 5 mm of the truth; placed on every keypoint
    it swings with the arms."""
    rec = Recording("jacks.mp4", 1920, 1080, K, H36M_JOINTS, fps=30.0, model="blazepose-full")
    true = to_camera(standing(ADULT) + [0.0, 0.0, 4000.0])
    uv = project(true, K)
    arms = np.array(["elbow" in j or "wrist" in j for j in H36M_JOINTS])
    legs = np.array(["knee" in j or "ankle" in j for j in H36M_JOINTS])
    conf = np.where(legs, 0.05, 0.9)
    for i in range(40):
        model = true - true[0]
        model[arms, 2] += 300.0 * np.sin(i / 3)
        placed = model + solve_root_translation(model, uv, conf, K)
        rec.frames.append(Frame(i, i / 30.0, [Person(0, 0.9, np.r_[uv.min(0), uv.max(0)], uv, placed, conf.copy())]))
    assert np.ptp([f.people[0].root[2] for f in rec.frames]) > 50.0
    out = scale_recording(rec, MetricOptions(floor=False))
    depths = np.array([f.people[0].root[2] for f in out.frames])
    assert np.abs(depths - true[0, 2]).max() < 5.0
