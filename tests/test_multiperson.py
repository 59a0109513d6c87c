"""Several people: the MoveNet MultiPose detector, crops that hold one person, the tracker."""

import json
from dataclasses import replace

import numpy as np
import pytest

from conftest import DATA, TRACKER, run_posecam
from posecam import EstimatorOptions, PoseEstimator
from posecam.inference.detector import Detection
from posecam.inference.roi import Roi
from posecam.io.media import open_media, read_image
from posecam.geometry.boxes import box_iou
from posecam.results import Frame, Person
from posecam.tracking import TRACKING, ConfirmedIds, Tracker, foreign_joints

FPS = 10.0      # the frame rate the tracker's scripted videos below play at (searches every 0.5 s = 5 frames)


@pytest.fixture(scope="module")
def people(estimator):
    assert estimator.options.max_people == EstimatorOptions().max_people   # the defaults
    return estimator


def _confident_box(p, min_conf=0.5):
    uv = p.keypoints_2d[p.confidence >= min_conf]
    return np.concatenate([uv.min(axis=0), uv.max(axis=0)])


def _clip():
    return [rgb for _, _, rgb in open_media(DATA / "two_people_cam03_30f.mp4").frames()]


@pytest.mark.parametrize("image, count", [("basketball2.png", 2), ("messi5.jpg", 1), ("fruits.jpg", 0)])
def test_people_counted_in_photos(people, image, count):
    assert len(people.predict_image(read_image(DATA / image)).people) == count


def test_tiles_find_each_person_once(people):
    # searched for people 40 px tall, the photos are cut in overlapping tiles: one detection each
    for image, count in (("basketball2.png", 2), ("messi5.jpg", 1)):
        rgb = read_image(DATA / image)
        h, w = rgb.shape[:2]
        assert len(people.detector.tiles(w, h, 40)) >= 4
        confident = [d for d in people.detector(rgb, 40) if d.score >= people.detector.start_score]
        assert len(confident) == count, image


VTEST = json.loads((DATA / "vtest_people" / "people.json").read_text())["people"]
BORDER = json.loads((DATA / "border" / "people.json").read_text())
MARKED = {**{f"vtest_people/vtest_{f}.jpg": [(p[f], 1.0) for p in VTEST.values()] for f in ("175", "190", "205")},
          **{f"border/{name}": [(m["box"], m["visible"]) for m in marks] for name, marks in BORDER.items()}}


@pytest.mark.parametrize("name", sorted(MARKED))
def test_the_search_finds_each_person_marked_by_hand_once_and_whole(people, name):
    """vtest.avi's frames and the border photos, each person's box marked by hand, searched as a
    video's first frame is (the whole image, its tiles for people 40 px tall, the quarter
    turns): each confident detection on a marked person (the one it overlaps most, IoU over
    0.3) is the only one on them, the runs that saw them merged into one by their boxes (vtest
    175's leather jacket twice, keypoints unlike) or their keypoints (vtest 300's man at the
    left edge, boxes apart); and it holds 85 % of their height when half of them or more is in
    view (basketball1's player cut by the left edge: not a tile's detection cut by the tile's
    top, 74 %)."""
    from posecam.inference.detector import detect_any_turn

    marks = MARKED[name]
    boxes = np.array([box for box, _ in marks], float)
    found = [d for d in detect_any_turn(people.detector, read_image(DATA / name), 40) if d.score >= people.detector.start_score]
    iou = box_iou(np.array([d.box for d in found]).reshape(-1, 4), boxes)
    for i, (box, visible) in enumerate(marks):
        on = [d for d, row in zip(found, iou) if row.argmax() == i and row[i] > 0.3]
        assert len(on) <= 1, (box, [d.box.round() for d in on])
        if on and visible >= 0.5:
            assert min(on[0].box[3], box[3]) - max(on[0].box[1], box[1]) >= 0.85 * (box[3] - box[1]), (box, on[0].box)


def test_search_is_set_by_the_people_not_by_max_people():
    image = read_image(DATA / "basketball2.png")
    one = PoseEstimator(EstimatorOptions(max_people=1)).predict_image(image)
    assert len(one.people) == 1
    # the second player is not lost in silence: listed as dropped over max_people, with the detector's score
    (over,) = [d for d in one.dropped if d.stage == "max_people"]
    assert over.score >= 0.25 and over.bbox.shape == (4,)
    assert box_iou(over.bbox, one.people[0].bbox)[0, 0] < 0.3   # the other player, not the one kept


def test_dropped_people_are_counted_and_listed_in_the_json(tmp_path):
    out = tmp_path / "two.json"
    r = run_posecam("predict", DATA / "basketball2.png", "--max-people", "1", "-o", out)
    assert r.returncode == 0, r.stderr
    frame = json.loads(out.read_text())["inputs"][0]["frames"][0]
    assert len(frame["people"]) == 1
    assert [d["stage"] for d in frame["dropped"]] == ["max_people"] and len(frame["dropped"][0]["bbox"]) == 4
    assert "1 over --max-people" in " ".join(r.stdout.split())   # the summary counts them


def test_two_players_get_one_skeleton_each(people):
    frame = people.predict_image(read_image(DATA / "basketball2.png"))
    a, b = sorted(frame.people, key=lambda p: p.root[0])
    box_a, box_b = _confident_box(a), _confident_box(b)
    assert box_a[2] < box_b[0], (box_a, box_b)          # no skeleton reaches into the other player
    assert a.root[0] < b.root[0] and abs(a.root[2] - b.root[2]) < 3000


def test_clip_of_two_people_keeps_two_ids_and_one_person_per_skeleton(people):
    frames = _clip()
    detector = people.detector
    results = list(people.track(frames))
    counts = [len(f.people) for f in results]
    assert sum(c == 2 for c in counts) >= 0.8 * len(frames), counts
    ids = {p.id for f in results for p in f.people}
    assert len(ids) == 2, ids
    last = {}
    for rgb, f in zip(frames, results):
        dets = detector(rgb)
        for p in f.people:
            # the confident joints lie on the person's own detection, not on the neighbour's
            own = max(dets, key=lambda d: box_iou(d.box[None], _confident_box(p)[None])[0, 0])
            pad = 0.15 * (own.box[2:] - own.box[:2])
            uv = p.keypoints_2d[p.confidence >= 0.5]
            inside = ((uv >= own.box[:2] - pad) & (uv <= own.box[2:] + pad)).all(axis=1)
            assert inside.mean() >= 0.85, (f.index, p.id, inside.mean())
            # an id stays on its person: its confident pelvis moves little between frames
            if p.confidence[0] < 0.5:
                continue
            if p.id in last:
                assert np.linalg.norm(p.keypoints_2d[0] - last[p.id]) < 60, (f.index, p.id)
            last[p.id] = p.keypoints_2d[0]


def _det(box, score=0.8):
    box = np.asarray(box, float)
    return Detection(score, box, np.zeros((0, 2)), np.zeros(0), Roi.around_points(box.reshape(2, 2)))


def _run(tracker, frames):
    """Detections per frame -> {detection index: track id} per frame, the pose model's part
    played by the detection itself (a track the detector missed: the pose model finds nobody)."""
    out = []
    for dets in frames:
        tracks = tracker.begin_frame(dets)
        tracker.end_frame(tracks, [t.detection is not None for t in tracks], [None] * len(tracks),
                          [None] * len(tracks), [t.roi for t in tracks])
        out.append({dets.index(t.detection): t.id for t in tracks if t.detection is not None})
    return out


def test_ids_survive_a_crossing():
    # two people walk past each other (the boxes overlap for several frames)
    frames = []
    for f in range(30):
        xa, xb = 100 + 10 * f, 400 - 10 * f
        frames.append([_det([xa, 100, xa + 80, 300]), _det([xb, 110, xb + 80, 310])])
    ids = _run(Tracker(TRACKER, fps=FPS), frames)
    assert all(i == ids[0] for i in ids), ids


def test_ids_survive_a_short_occlusion():
    frames = []
    for f in range(40):
        x = 100 + 5 * f
        a, b = _det([x, 100, x + 80, 300]), _det([600, 100, 680, 300])
        frames.append([b] if 10 <= f < 20 else [a, b])      # a hidden for 10 frames
    ids = _run(Tracker(TRACKER, fps=FPS), frames)
    first_a = ids[0][0]
    assert ids[25][0] == first_a and ids[25][1] == ids[0][1]
    assert len({t for i in ids for t in i.values()}) == 2


def test_someone_hidden_while_walking_away_is_found_again_at_their_last_size():
    """A person walking away (the box shrinking 3 px a frame) hidden for 28 frames, then seen
    again at the size they had when hidden, where their walk took them: the same track (a box
    that went on shrinking while unseen would be under half as tall and match nobody)."""
    def walking(f):
        h = 200 - 3 * f
        return [100 + 4 * f, 300 - h, 100 + 4 * f + h / 2.5, 300]
    frames = [[_det(walking(f))] for f in range(20)] + [[] for _ in range(28)] + \
             [[_det(np.array(walking(19)) + [4 * (f - 19), 0, 4 * (f - 19), 0])] for f in range(48, 52)]
    ids = _run(Tracker(TRACKER, fps=FPS), frames)
    assert ids[-1] == {0: ids[0][0]}, ids[-5:]


def test_a_track_is_not_matched_to_someone_who_does_not_overlap_it():
    """Someone followed for 10 frames leaves, and in the next frame a person appears at the
    other side of the image (their boxes share nothing: cost 1, above the gate): a new track,
    not the old one's id; a weak detection there does not keep the old track either."""
    walk = [[_det([100 + 5 * f, 100, 180 + 5 * f, 300])] for f in range(10)]
    far = [900, 120, 980, 320]
    ids = _run(Tracker(TRACKER, fps=FPS), walk + [[_det(far)]])
    assert ids[-1] == {0: ids[0][0] + 1}, ids[-2:]
    tracker = Tracker(replace(TRACKER, high_score=0.5), fps=FPS)
    _run(tracker, walk + [[_det(far, 0.2)]])
    assert tracker.tracks[0].lost == 1 and len(tracker.tracks) == 1


def test_weak_detections_are_matched_under_a_tighter_gate():
    """A person standing still, then only a weak detection half a box to the side (IoU 1/3:
    cost 0.67, within the first stage's gate of 0.8, not the weak ones' 0.5): the track is
    not kept by it; a weak one a tenth of a box to the side (cost 0.18) keeps it."""
    still = [[_det([100, 100, 180, 300])] for _ in range(10)]
    for dx, kept in ((40, False), (8, True)):
        tracker = Tracker(replace(TRACKER, high_score=0.5), fps=FPS)
        ids = _run(tracker, still + [[_det([100 + dx, 100, 180 + dx, 300], 0.2)]])
        assert (ids[-1] == {0: ids[0][0]}) is kept and (tracker.tracks[0].lost == 0) is kept, (dx, ids[-1])


def test_a_track_moves_on_with_its_speed_while_unseen():
    """The box filter's prediction: someone walking 8 px a frame, unseen for 6 frames, is
    predicted near where the walk took them (not where they were last seen)."""
    tracker = Tracker(TRACKER, fps=FPS)
    _run(tracker, [[_det([100 + 8 * f, 100, 180 + 8 * f, 300])] for f in range(15)] + [[] for _ in range(6)])
    (track,) = tracker.tracks
    assert abs(track.box[0] - (100 + 8 * 20)) < 12, track.box


def test_a_weak_detection_keeps_a_track_but_does_not_start_one():
    tracker = Tracker(replace(TRACKER, high_score=0.5), fps=FPS)
    ids = _run(tracker, [[_det([0, 0, 100, 200], 0.9)], [_det([5, 0, 105, 200], 0.2)]])
    assert ids == [{0: 0}, {0: 0}]
    assert _run(Tracker(replace(TRACKER, high_score=0.5), fps=FPS), [[_det([0, 0, 100, 200], 0.2)]]) == [{}]


def test_joints_on_a_neighbour_are_found():
    k = 17
    own_kp = np.column_stack([np.full(k, 100.0), np.linspace(100, 300, k)])
    other_kp = own_kp + [60, 0]
    own = Detection(0.9, np.array([80, 90, 120, 310.0]), own_kp, np.ones(k), Roi(100, 200, 300))
    other = Detection(0.9, np.array([140, 90, 180, 310.0]), other_kp, np.ones(k), Roi(160, 200, 300))
    pose = own_kp.copy()
    pose[13:] = other_kp[13:]                      # knees and ankles taken from the neighbour
    foreign = foreign_joints(pose, np.ones(k), own, [other])
    assert foreign.tolist() == [False] * 13 + [True] * 4
    assert not foreign_joints(own_kp, np.ones(k), own, [other]).any()
    # hands joined: the neighbour's right wrist 12 px from his, the pose's 8 px off his own
    # (nearer the neighbour's, yet within a tenth of his box's diagonal): his still
    holding = Detection(0.9, other.box, other_kp.copy(), np.ones(k), other.roi)
    holding.keypoints[10] = own_kp[10] + [12, 0]
    pose = own_kp.copy()
    pose[10] += [8, 0]
    assert not foreign_joints(pose, np.ones(k), own, [holding]).any()


def test_min_cost_assignment_matches_scipy_on_random_matrices():
    """The tracker's own Hungarian method finds assignments as cheap as scipy's (the reference)."""
    from scipy.optimize import linear_sum_assignment

    from posecam.tracking import min_cost_assignment

    rng = np.random.default_rng(7)
    for trial in range(400):
        n, m = rng.integers(1, 9, size=2)
        cost = rng.random((n, m)) if trial % 2 else rng.integers(0, 3, size=(n, m)).astype(float)
        rows, cols = min_cost_assignment(cost)
        ref_rows, ref_cols = linear_sum_assignment(cost)
        assert len(rows) == min(n, m) and len(set(rows)) == len(rows) and len(set(cols)) == len(cols)
        assert all(r < n for r in rows) and all(c < m for c in cols), (n, m, rows, cols)
        assert np.isclose(cost[rows, cols].sum(), cost[ref_rows, ref_cols].sum())


def test_tiles_follow_the_image_and_its_smallest_people(people):
    d = people.detector
    assert d.tiles(768, 576, None) == []                       # no size asked: the whole image only
    assert len(d.tiles(768, 576, 40)) == 9                      # vtest.avi before anyone is seen: 3 x 3
    assert len(d.tiles(768, 576, 55)) == 6                      # ... once its people are seen: 3 x 2
    assert d.tiles(1080, 1920, 900) == []                       # people a metre tall in a portrait video
    for x0, y0, x1, y1 in d.tiles(768, 576, 40):
        assert 0 <= x0 < x1 <= 768 and 0 <= y0 < y1 <= 576


def _follow(tracker, dets, frames, width=1000, height=800):
    """Frames of detections (the same ones, or `dets(frame)`), the pose model finding each
    tracked person; the frames on which the tracker asked for the detector."""
    asked = []
    for f in range(frames):
        run = tracker.detector_run(width, height)
        asked.append(run is not None)
        tracks = tracker.begin_frame((dets(f) if callable(dets) else dets) if run is not None else None)
        tracker.end_frame(tracks, [True] * len(tracks), [None] * len(tracks), [None] * len(tracks),
                          [t.roi for t in tracks])
    return [f for f, run in enumerate(asked) if run]


def test_detector_runs_more_often_while_people_may_be_missing():
    alone = [_det([400, 200, 480, 400])]                        # one person in the middle
    asked = _follow(Tracker(TRACKER, fps=FPS), alone, 45)                       # (10 frames/s: searches every 0.5 s = 5 frames)
    assert asked[:3] == [0, 5, 10] and asked[3:] == [25, 40]    # confirmed after 3 runs: every 15 frames
    standing = [_det([960, 200, 1000, 400])]                    # standing at the right edge: every 15
    assert _follow(Tracker(TRACKER, fps=FPS), standing, 45)[3:] == [25, 40]
    entering = lambda f: [_det([960 - 2 * f, 200, 1000 - 2 * f, 400])]   # walking in at the edge: every 5
    assert _follow(Tracker(TRACKER, fps=FPS), entering, 25) == list(range(0, 25, 5))    # (it leaves the edge at frame 25)
    crowd = [_det([100 + 150 * i, 200, 180 + 150 * i, 400]) for i in range(3)]   # 3 people: every 5
    assert _follow(Tracker(TRACKER, fps=FPS), crowd, 40) == list(range(0, 40, 5))


def test_someone_the_detector_misses_stays_with_the_pose_model():
    tracker = Tracker(TRACKER, fps=FPS, policy=replace(TRACKING, coast=2))
    _follow(tracker, [_det([400, 200, 480, 400])], 1)
    for run in range(3):                                        # detector runs that find nobody
        tracks = tracker.begin_frame([])
        followed = [t for t in tracks if t.detection is None]
        assert len(followed) == (1 if run < 2 else 0), run      # posed from its last crop, twice
        tracker.end_frame(tracks, [True] * len(tracks), [None] * len(tracks), [None] * len(tracks),
                          [t.roi for t in tracks])


def test_a_run_for_an_overlap_alone_searches_only_around_those_people():
    tiles = [(0, 0, 600, 450), (400, 0, 1000, 450), (0, 350, 600, 800), (400, 350, 1000, 800)]
    tracker = Tracker(TRACKER, fps=FPS)
    pair = [_det([100, 100, 180, 300]), _det([150, 110, 230, 310])]     # overlapping, top left
    apart = _det([800, 500, 880, 700])                                  # alone, bottom right
    asked = _follow(tracker, pair + [apart], 9)
    assert asked == list(range(9))                              # the overlap asks on every frame
    run = tracker.detector_run(1000, 800)
    assert run is not None
    search = tracker.search(run, tiles, 1000, 800)
    assert not search.whole and len(search.regions) == 1        # one region, not the whole image nor a tile
    (x0, y0, x1, y1) = search.regions[0]
    assert x0 <= 100 and y0 <= 100 and x1 >= 230 and y1 >= 310   # holding the pair ...
    assert max(x1 - x0, y1 - y0) <= 4 * 200 and x1 < 800         # ... at their scale, not the one apart
    tracks = tracker.begin_frame(pair, search=search)           # the region finds the pair only
    assert {t.detection is None for t in tracks} == {False, True}
    (alone,) = [t for t in tracks if t.detection is None]
    assert alone.unseen == 0 and alone.lost == 0                # not searched there: not missed either
    for _ in range(5):                                          # frames the pose model alone follows (0.5 s)
        tracker.end_frame(tracks, [True] * 3, [None] * 3, [None] * 3, [t.roi for t in tracks])
        tracks = tracker.begin_frame(None)
    run = tracker.detector_run(1000, 800)                       # a crowd's scheduled run: everywhere
    assert run is not None and run.asking == []
    search = tracker.search(run, tiles, 1000, 800)
    assert search.whole and search.regions == tiles
    tracks = tracker.begin_frame(pair, search=search)           # searched everywhere, missed
    assert alone.unseen == 1 and alone in tracks


def test_someone_just_lost_is_searched_for_where_they_were():
    tracker = Tracker(TRACKER, fps=FPS)
    a, b = _det([100, 100, 180, 300]), _det([700, 100, 780, 300])
    _follow(tracker, [a, b], 30)                                # both followed and confirmed
    assert tracker.detector_run(1000, 800) is None              # nobody missing, no run due
    tracks = tracker.begin_frame(None)
    tracker.end_frame(tracks, [t.roi.cx < 500 for t in tracks], [None] * 2, [None] * 2, [t.roi for t in tracks])
    run = tracker.detector_run(1000, 800)                       # b's pose lost: a run at once ...
    assert run is not None
    (region,) = tracker.search(run, [(0, 0, 1000, 800)], 1000, 800).regions
    assert region[0] <= 700 and region[2] >= 780 and region[0] > 180   # ... around b only


def test_no_search_about_someone_lost_past_the_border():
    """Someone followed beside another is lost, their box carried past the image's right
    border: the run their loss asks for would search the strip of their region the border
    leaves, 10 px wide (resized to the detector's input, it holds nobody): nothing is searched
    (a strip under TRACKING.min_region_px)."""
    tracker = Tracker(TRACKER, fps=FPS)
    _follow(tracker, [_det([400, 200, 480, 400]), _det([880, 200, 960, 400])], 12)
    gone = max(tracker.tracks, key=lambda t: t.box[0])
    gone.kalman.x[:2] = [1130, 300]                             # box x 1090-1170, its region from 990
    tracks = tracker.begin_frame(None)
    tracker.end_frame(tracks, [t is not gone for t in tracks], [None] * 2, [None] * 2, [t.roi for t in tracks])
    run = tracker.detector_run(1000, 800)
    assert run is not None and run.asking == [gone]
    search = tracker.search(run, [(0, 0, 1000, 800)], 1000, 800)
    assert not search.whole and search.regions == []


def test_searches_everywhere_are_scheduled_in_seconds():
    crowd = [_det([100 + 150 * i, 200, 180 + 150 * i, 400]) for i in range(3)]
    assert _follow(Tracker(TRACKER, fps=10), crowd, 20) == list(range(0, 20, 5))        # 0.5 s at 10 frames/s
    assert _follow(Tracker(TRACKER, fps=20), crowd, 40) == list(range(0, 40, 10))       # ... at 20 frames/s


def _person(box) -> Person:
    box = np.asarray(box, float)
    return Person(-1, 0.9, box, np.zeros((17, 2)), np.zeros((17, 3)), np.ones(17))


def test_ids_are_numbered_only_for_confirmed_tracks():
    """A steady person, a detection on frames 5-7 only (a false start), a person who comes at
    frame 8, the detector run on every frame: the two people take ids 0 and 1 once confirmed,
    from their first frame on; the false start (matched 3 times, missed at 8, before it was
    followed for `confirm_frames`) takes none and its poses are listed as dropped
    ("unconfirmed"); every frame comes out, in order, at most `confirm_frames` late."""
    tracker = Tracker(TRACKER, fps=FPS)
    held, out = ConfirmedIds(tracker), []
    a, b, c = [400, 200, 480, 400], [100, 500, 160, 620], [700, 200, 780, 400]
    for f in range(30):
        dets = [_det(a)] + ([_det(b)] if 5 <= f <= 7 else []) + ([_det(c)] if f >= 8 else [])
        tracks = tracker.begin_frame(dets)
        kept = tracker.end_frame(tracks, [t.detection is not None for t in tracks], [None] * len(tracks),
                                 [None] * len(tracks), [t.roi for t in tracks])
        frame = Frame(f, 0.0, [_person(tracks[i].box) for i in kept])
        released = held.push(frame, [tracks[i] for i in kept], frame)
        assert len(out) + len(released) >= f + 1 - tracker.policy.confirm_frames
        out += released
    out += held.flush()
    assert [f.index for f in out] == list(range(30))
    assert [[p.id for p in f.people] for f in out[:8]] == [[0]] * 8
    assert [sorted(p.id for p in f.people) for f in out[8:]] == [[0, 1]] * 22
    assert [[d.stage for d in f.dropped] for f in out[4:9]] == [[], ["unconfirmed"], ["unconfirmed"], ["unconfirmed"], []]


def test_a_person_the_detector_merges_with_a_neighbour_stays_followed():
    """Two overlapping people, the detector finding one of them on 8 runs in a row: the other
    is still followed by the pose model (the misses of someone overlapping a neighbour do not
    count), and lost as usual once apart and missed `coast` times."""
    tracker = Tracker(TRACKER, fps=FPS, policy=replace(TRACKING, coast=2))
    front, behind = [400, 200, 500, 420], [440, 210, 520, 400]
    _follow(tracker, [_det(front), _det(behind)], 12)
    for run in range(8):
        tracks = tracker.begin_frame([_det(front)])
        assert len(tracks) == 2, run
        tracker.end_frame(tracks, [True] * 2, [None] * 2, [None] * 2, [t.roi for t in tracks])
    (hidden,) = [t for t in tracker.tracks if t.detection is None]
    hidden.kalman.x[:2] = [800, 300]                            # apart now
    for run in range(3):
        tracks = tracker.begin_frame([_det(front)])
        tracker.end_frame(tracks, [True] * len(tracks), [None] * len(tracks), [None] * len(tracks),
                          [t.roi for t in tracks])
    assert hidden.lost > 0
