"""Mutation check: named breakages of posecam's core, each of which its tests must catch.

    python tests/mutants.py               # every mutant, two at a time
    python tests/mutants.py --jobs 1 -k lift    # the mutants whose name contains "lift"
    python tests/mutants.py --list

Each mutant is one exact snippet of one source file and its replacement. For each, posecam/ is
copied to a temporary folder (the models linked, not copied), the snippet replaced there (it
must occur exactly once: a snippet that moved or changed is an error, so a refactor is noticed
and the table updated), and every test of the mutant's stage (the test files of its stage's
modules: STAGES) runs with that copy first on the path, the tests the table names for it first.
A mutant is killed only when a test fails on an assertion (an AssertionError, or pytest's own
fail: `pytest.raises` that saw nothing raised); the first such failure stops its run. A crash
(an import or collection error, any other exception), a timeout, or tests that all pass leave it
alive. The unmutated tests of every stage run once first and must all pass. Exit status: 0 when
every mutant is killed, 1 otherwise (a survivor, a missing snippet, a failing baseline).

Not collected by pytest (not named test_*). About ten minutes on two cores.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TIMEOUT_S = 600                 # s, a mutant's run; the unmutated run of every stage gets 3 times this
NO_TESTS = 5                    # pytest's exit status when it collected nothing
PLUGIN = "posecam_mutant_verdict"

# A pytest plugin, written next to the copies: the tests named first run first, and the first
# test that fails on an assertion is recorded (in MUTANT_VERDICT) and stops the run.
PLUGIN_SOURCE = """
import json, os
import pytest

FIRST = json.loads(os.environ.get("MUTANT_FIRST", "[]"))


def _named(nodeid):
    return any(nodeid == t or nodeid.startswith(t + "[") or nodeid.startswith(t + "::") for t in FIRST)


def pytest_collection_modifyitems(items):
    items.sort(key=lambda item: not _named(item.nodeid))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if report.when == "call" and report.failed and call.excinfo is not None \\
            and call.excinfo.errisinstance((AssertionError, pytest.fail.Exception)):
        with open(os.environ["MUTANT_VERDICT"], "w") as f:
            json.dump({"test": item.nodeid, "line": str(call.excinfo.value).splitlines()[0][:120]
                       if str(call.excinfo.value) else call.excinfo.typename}, f)
        item.session.shouldstop = "a test failed on an assertion"
"""


@dataclass(frozen=True)
class Mutant:
    name: str
    file: str                   # relative to the repository
    original: str               # exact snippet, found exactly once in the file
    replacement: str
    tests: tuple[str, ...]      # pytest node ids or files (relative to the repository) run first: these catch it
    stage: tuple[str, ...] = () # the test files of its stage's modules (STAGES), all run


CAMERA = "tests/test_camera.py"
CALIB = "tests/test_calibration_io.py"
CONSENSUS = "tests/test_consensus.py"
FUSION = "tests/test_fusion.py"
TRACKING = "tests/test_multiperson.py"
METRIC = "tests/test_metric.py"

MUTANTS = (
    # ---- the lift ----------------------------------------------------------------------------
    Mutant("lift: fy replaced by fx in the root translation", "posecam/geometry/lift.py",
           "    a[1::2, 1] = k.fy\n    a[1::2, 2] = -dv\n    b[1::2] = dv * relative[:, 2] - k.fy * relative[:, 1]",
           "    a[1::2, 1] = k.fx\n    a[1::2, 2] = -dv\n    b[1::2] = dv * relative[:, 2] - k.fx * relative[:, 1]",
           (f"{CAMERA}::test_root_translation_uses_each_axis_own_focal_length",
            "tests/test_predict.py::test_non_square_pixels_put_the_person_on_the_keypoints_rays")),
    Mutant("lift: cx for cy in the root translation", "posecam/geometry/lift.py",
           "dv = uv[:, 1] - k.cy", "dv = uv[:, 1] - k.cx",
           (f"{CAMERA}::test_root_translation_uses_each_axis_own_focal_length",)),
    Mutant("lift: weights misaligned with the joints' equations", "posecam/geometry/lift.py",
           "np.repeat(np.clip(weights, 0.0, None), 2)", "np.tile(np.clip(weights, 0.0, None), 2)",
           (f"{CAMERA}::test_root_translation_weighs_each_joint_with_its_own_weight",)),
    Mutant("lift: back-projection divides y by fx", "posecam/geometry/lift.py",
           "y = (uv[..., 1] - k.cy) * z / k.fy", "y = (uv[..., 1] - k.cy) * z / k.fx",
           (f"{CAMERA}::test_a_pinhole_example_worked_by_hand",)),
    # ---- cameras and the readers -------------------------------------------------------------
    Mutant("toml: rotation transposed", "posecam/io/calibration.py",
           'rotation = check.rotation(table["rotation"], "rotation")',
           'rotation = check.rotation(table["rotation"], "rotation").T',
           (f"{CALIB}::test_foreign_calibration_projects_as_opencv_does",)),
    Mutant("toml: Rodrigues vector's sign flipped", "posecam/io/validate.py",
           "return cv2.Rodrigues(a)[0]", "return cv2.Rodrigues(-a)[0]",
           (f"{CALIB}::test_foreign_calibration_projects_as_opencv_does",)),
    Mutant("toml: translation taken as mm", "posecam/io/calibration.py",
           "translation * 1000.0, dist)", "translation, dist)",
           (f"{CALIB}::test_foreign_calibration_projects_as_opencv_does",)),
    Mutant("camera: cy read from cx's cell", "posecam/geometry/camera.py",
           "float(k[0, 2]), float(k[1, 2]), source)", "float(k[0, 2]), float(k[0, 2]), source)",
           (f"{CALIB}::test_foreign_calibration_projects_as_opencv_does",)),
    Mutant("camera: tangential distortion's terms swapped", "posecam/geometry/camera.py",
           "x, y = (x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),",
           "x, y = (x * radial + 2 * p2 * x * y + p1 * (r2 + 2 * x * x),",
           (f"{CALIB}::test_foreign_calibration_projects_as_opencv_does",)),
    Mutant("camera: undistortion skipped", "posecam/geometry/camera.py",
           "    if not k.distortion:\n        if not normalised:", "    if True:\n        if not normalised:",
           (f"{CALIB}::test_foreign_calibration_projects_as_opencv_does",)),
    Mutant("qualisys: rotation read by row", "posecam/io/calibration.py",
           '.reshape(3, 3).T,\n', '.reshape(3, 3),\n',
           (f"{CALIB}::test_qca_read_and_dispatch",)),
    Mutant("intrinsics: a JSON's fy ignored", "posecam/io/intrinsics.py",
           '"fy": doc.get("fy", doc["fx"])', '"fy": doc["fx"]',
           ("tests/test_intrinsics.py::test_json_file_with_values_or_matrix",)),
    Mutant("intrinsics: a matrix's cy from the wrong cell", "posecam/io/intrinsics.py",
           '"cy": m[1, 2]', '"cy": m[0, 2]',
           ("tests/test_intrinsics.py::test_json_file_with_values_or_matrix",)),
    Mutant("poses: fy read as fx", "posecam/io/poses.py",
           'for n in ("fx", "fy", "cx", "cy")),', 'for n in ("fx", "fx", "cx", "cy")),',
           ("tests/test_pose_files.py::test_json_has_the_documented_keys_and_round_trips",)),
    # ---- metric scale ------------------------------------------------------------------------
    Mutant("metric: the root placed again on every joint, the arms too", "posecam/scale/metric.py",
           "self._core[[i for role in CORE for i in skeleton.role(role)]] = 1.0", "self._core[:] = 1.0",
           (f"{METRIC}::test_the_roots_depth_does_not_follow_arms_misplaced_in_depth",)),
    Mutant("metric: frames not brought to their track's height", "posecam/scale/metric.py",
           "s = ts.scale * (ts.stature / h if np.isfinite(h) else 1.0)", "s = ts.scale",
           (f"{METRIC}::test_each_track_keeps_one_size_across_frames",)),
    Mutant("metric: the chain's share of the stature inverted", "posecam/scale/stature.py",
           "(leg + torso) / CHAIN_OF_STATURE", "(leg + torso) * CHAIN_OF_STATURE",
           (f"{METRIC}::test_stature_of_a_skeleton_whatever_its_pose",)),
    Mutant("metric: children in the floor's adult gauge", "posecam/scale/metric.py",
           "adults = [tid for tid in size if size[tid] >= SCALE.adult_cluster * max(size.values())]",
           "adults = list(size)",
           (f"{METRIC}::test_the_floor_puts_people_of_different_sizes_at_their_depths",)),
    Mutant("metric: a given height's scale inverted", "posecam/scale/metric.py",
           "metres * 1000.0 / h,", "h / (metres * 1000.0),",
           (f"{METRIC}::test_given_heights_by_rank_and_by_id",)),
    Mutant("metric: the pose model's size taken as near exact", "posecam/scale/policy.py",
           "model_sd: float = 0.06 ", "model_sd: float = 0.02 ",
           ("tests/test_depth_spread.py::test_the_depth_spread_covers_a_crowd_against_the_ground_the_camera_calibration_gives",)),
    Mutant("metric: the default lens's uncertainty left out of depth_sd", "posecam/scale/metric.py",
           "            return DEFAULT_FOCAL_SD\n", "            return 0.0\n",
           (f"{METRIC}::test_the_default_lens_is_in_the_depth_spread",)),
    Mutant("metric: someone never seen whole left without a size or spread", "posecam/scale/metric.py",
           "stat = {**dict.fromkeys(self._tracks, self._model_mm), **measured} if self._model_mm else measured",
           "stat = measured",
           (f"{METRIC}::test_someone_never_seen_whole_keeps_the_models_size_and_its_spread",)),
    Mutant("metric: a track measured far from the model's size trusted", "posecam/scale/metric.py",
           "and (not self._model_mm or abs(t.stature / self._model_mm - 1.0) <= SCALE.size_off)", "and True",
           (f"{METRIC}::test_a_track_measured_far_from_the_models_size_is_left_unmeasured",)),
    Mutant("metric: a track measured on a few of its frames trusted", "posecam/scale/metric.py",
           "t.heights.seen >= SCALE.seen_share * t.frames", "True",
           (f"{METRIC}::test_a_track_measured_on_a_few_of_its_frames_is_left_unmeasured_and_off_the_floor",)),
    Mutant("metric: someone cut at the knees not placed on the trunk", "posecam/scale/policy.py",
           "core_joints: int = 4", "core_joints: int = 6",
           (f"{METRIC}::test_the_trunk_alone_places_someone_whose_legs_are_out_of_view",)),
    Mutant("metric: a floor that makes someone a toddler or a giant kept", "posecam/scale/policy.py",
           "floor_stature_m: tuple[float, float] = (1.0, 2.3)", "floor_stature_m: tuple[float, float] = (0.0, 9.0)",
           (f"{METRIC}::test_a_floor_that_would_make_someone_a_toddler_is_refused",)),
    Mutant("heights: a list's doubtful ranks not told", "posecam/scale/heights.py",
           "ha - hb >= math.hypot(sa, sb)", "True",
           ("tests/test_heights.py::test_a_list_says_which_people_it_cannot_tell_apart",)),
    Mutant("metric: the people's lens not used on later frames", "posecam/scale/metric.py",
           "            frame = self._relensed(frame)\n", "            pass\n",
           (f"{METRIC}::test_frames_after_the_lens_is_decided_are_placed_through_it_too",)),
    # ---- consensus and the fusion of points -------------------------------------------------
    Mutant("consensus: Procrustes reflection guard removed", "posecam/multiview/consensus.py",
           "flip[..., 2] = np.sign(np.linalg.det(v @ ut))", "flip[..., 2] = 1.0",
           (f"{CONSENSUS}::test_procrustes_finds_a_rotation_and_never_a_reflection",)),
    Mutant("consensus: fused points weighted alike on every axis", "posecam/multiview/consensus.py",
           "[1.0, 1.0, depth_ratio ** -2]", "[1.0, 1.0, 1.0]",
           (f"{CONSENSUS}::test_fused_points_trust_each_views_depth_less_than_its_image_plane",
            f"{CONSENSUS}::test_a_person_fused_from_two_views_keeps_the_better_axis_of_each")),
    Mutant("fusion: a person's views fused alike on every axis", "posecam/multiview/fuse_people.py",
           "fused = fuse_points(pts, rot, w)", "fused = fuse_points(pts, rot, w, depth_ratio=1.0)",
           (f"{CONSENSUS}::test_a_person_fused_from_two_views_keeps_the_better_axis_of_each",)),
    Mutant("fusion: views not moved onto the triangulation", "posecam/multiview/fuse_people.py",
           "z = z + np.where((wa > 0).sum(axis=-1, keepdims=True) >= FUSION.anchor_joints, shift, 0.0)",
           "z = z + 0.0 * shift",
           (f"{CONSENSUS}::test_a_person_fused_from_two_views_keeps_the_better_axis_of_each",)),
    Mutant("fusion: a view that shows someone else fused in those frames", "posecam/multiview/policy.py",
           "max_view_angle: float = 0.04", "max_view_angle: float = 10.0",
           (f"{FUSION}::test_a_view_that_shows_someone_else_is_left_out_of_those_frames",)),
    Mutant("consensus: leave-one-out keeps the view itself", "posecam/multiview/consensus.py",
           "m, b, n = m_all - wi, b_all - wx, w.sum(axis=0) - w", "m, b, n = m_all, b_all, w.sum(axis=0)",
           (f"{CONSENSUS}::test_fused_points_trust_each_views_depth_less_than_its_image_plane",)),
    Mutant("consensus: every depth scaled with the focal length", "posecam/multiview/consensus.py",
           "return obs.xyz[..., 2] + (g - 1.0) * obs.root_depth()[..., None]", "return g * obs.xyz[..., 2]",
           (f"{CONSENSUS}::test_a_focal_scale_moves_the_root_depth_and_keeps_the_metric_skeleton",)),
    Mutant("consensus: fy refitted from fx", "posecam/multiview/consensus.py",
           "out[0], out[1] = g * assumed.intrinsics.fx, g * assumed.intrinsics.fy",
           "out[0], out[1] = g * assumed.intrinsics.fx, g * assumed.intrinsics.fx",
           (f"{CONSENSUS}::test_a_focal_scale_moves_the_root_depth_and_keeps_the_metric_skeleton",)),
    # ---- bundle adjustment -----------------------------------------------------------------
    Mutant("bundle: Rodrigues rotation's sign flipped", "posecam/geometry/rotation.py",
           "np.eye(3) + np.sin(theta) * kx", "np.eye(3) - np.sin(theta) * kx",
           (f"{CONSENSUS}::test_bundle_adjustment_recovers_a_perturbed_rig_and_its_metric_scale",)),
    Mutant("bundle: square pixels assumed in the residuals", "posecam/multiview/bundle.py",
           "proj = p[self.obs_v, LOG_F, None] * self.axes[self.obs_v] * pc[:, :2]",
           "proj = p[self.obs_v, LOG_F, None] * pc[:, :2]",
           (f"{CONSENSUS}::test_bundle_adjustment_recovers_a_perturbed_rig_and_its_metric_scale",)),
    Mutant("bundle: bones' scale inverted", "posecam/multiview/bundle.py",
           "ratio = bones_mm[None] / lengths", "ratio = lengths / bones_mm[None]",
           (f"{CONSENSUS}::test_bundle_adjustment_recovers_a_perturbed_rig_and_its_metric_scale",)),
    Mutant("bundle: the reference camera free", "posecam/multiview/bundle.py",
           "others = [i for i in range(n_v) if i != ref]", "others = list(range(n_v))",
           (f"{CONSENSUS}::test_bundle_adjustment_recovers_a_perturbed_rig_and_its_metric_scale",)),
    Mutant("bundle's solver: the soft-L1 loss not weighing the residuals", "posecam/multiview/schur_lm.py",
           "sw = (1 + (r / f_scale) ** 2) ** -0.25", "sw = np.ones_like(r)",
           ("tests/test_schur_lm.py::test_the_solver_reaches_scipys_minimum",)),
    Mutant("bundle's solver: the points' blocks added to the cameras', not eliminated",
           "posecam/multiview/schur_lm.py", "s = a_f + lam * np.diag(d_cam) - e.transpose",
           "s = a_f + lam * np.diag(d_cam) + e.transpose",
           ("tests/test_schur_lm.py::test_the_solver_reaches_scipys_minimum",)),
    Mutant("bundle's solver: a slot at its bound pushed past it", "posecam/multiview/schur_lm.py",
           "held = ((x[:n_cam] <= lower) & (g_c > 0)) | ((x[:n_cam] >= upper) & (g_c < 0))",
           "held = np.zeros(n_cam, bool)",
           ("tests/test_schur_lm.py::test_a_slot_held_at_its_bound_and_the_rest_at_their_best",)),
    Mutant("bundle: log focal length's derivative not times f", "posecam/multiview/bundle.py",
           "cam[:, :, LOG_F] = f * pc[:, :2]", "cam[:, :, LOG_F] = pc[:, :2]",
           (f"{CONSENSUS}::test_bundle_adjustment_derivatives_are_the_residuals_own",)),
    Mutant("bundle: rotation's derivative with its sign flipped", "posecam/multiview/bundle.py",
           "d_rot = np.cross(np.swapaxes(rj, 1, 2)[v], rx[:, None, :])",
           "d_rot = np.cross(rx[:, None, :], np.swapaxes(rj, 1, 2)[v])",
           (f"{CONSENSUS}::test_bundle_adjustment_derivatives_are_the_residuals_own",)),
    # ---- synchronisation -------------------------------------------------------------------
    Mutant("sync: calibrated sub-frame step's sign flipped", "posecam/multiview/rig_sync.py",
           "return round(float(o + np.clip(", "return round(float(o - np.clip(",
           (f"{FUSION}::test_calibrated_sync_finds_sub_frame_offsets",)),
    Mutant("sync: calibrated views shifted the wrong way", "posecam/multiview/rig_sync.py",
           "u = np.stack([shift(a, o, n) for a, o in zip(uv, offsets)])",
           "u = np.stack([shift(a, -o, n) for a, o in zip(uv, offsets)])",
           (f"{FUSION}::test_calibrated_sync_finds_sub_frame_offsets",)),
    Mutant("sync: motion correlation's lag flipped", "posecam/multiview/motion_sync.py",
           "a, b = shift(ref, -lag / 2, n), shift(other, lag / 2, n)",
           "a, b = shift(ref, lag / 2, n), shift(other, -lag / 2, n)",
           (f"{FUSION}::test_motion_offset_of_signals_shifted_by_a_known_fraction",)),
    Mutant("sync: motion peak's parabola sign flipped", "posecam/multiview/motion_sync.py",
           "return float(lags[k] + 0.5 * (c0 - c2) / den", "return float(lags[k] - 0.5 * (c0 - c2) / den",
           (f"{FUSION}::test_motion_offset_of_signals_shifted_by_a_known_fraction",)),
    Mutant("sync: people too still synchronised anyway", "posecam/multiview/policy.py",
           "min_motion: float = 45.0", "min_motion: float = 0.0",
           ("tests/test_session.py::test_a_still_take_joins_the_session_and_alone_is_refused_with_what_helps",)),
    # ---- the coarse sync and the views' agreement -------------------------------------------
    Mutant("coarse sync: the lag's sign flipped", "posecam/multiview/coarse_sync.py",
           "at = int(lags[np.nanargmax(score)]) * step", "at = -int(lags[np.nanargmax(score)]) * step",
           ("tests/test_sync.py::test_coarse_offsets_of_views_cut_at_different_frames",)),
    Mutant("coarse sync: a pairing's lag scored with another pairing", "posecam/multiview/coarse_sync.py",
           "found.append((at, pairing))", "found.append((at, pairings[len(found)]))",
           ("tests/test_sync.py::test_a_track_that_shares_no_bones_leaves_the_other_pairings_lags_alone",)),
    Mutant("coarse sync: bones compared without the rotation between the cameras", "posecam/multiview/coarse_sync.py",
           'corr = np.einsum("lij,lji->l", r, centred)', 'corr = np.einsum("lii->l", centred)',
           ("tests/test_sync.py::test_bones_seen_by_two_turned_cameras_correlate_at_their_lag_only",)),
    Mutant("coarse sync: the bones' poses correlated, not their motion", "posecam/multiview/coarse_sync.py",
           'out[k, 9:18] = np.einsum("mbi,mbj->ij", cb, ca).ravel()',
           'out[k, 9:18] = np.einsum("mbi,mbj->ij", pb, pa).ravel()',
           ("tests/test_sync.py::test_a_resample_weighs_frames_and_columns_as_drawing_them_again_would",)),
    Mutant("sync: a resample's bones correlated as poses, not motion", "posecam/multiview/coarse_sync.py",
           "centred = h - sb[..., :, None] * sa[..., None, :] / each[..., None]", "centred = h",
           ("tests/test_sync.py::test_bones_seen_by_two_turned_cameras_correlate_at_their_lag_only",)),
    Mutant("same scene: views whose people move unlike the reference's kept", "posecam/multiview/policy.py",
           "min_same_motion: float = 0.38", "min_same_motion: float = -1.0",
           ("tests/test_camera_gate.py::test_a_view_of_another_time_is_not_fused",)),
    Mutant("sync: the views' agreement read at the opposite offset", "posecam/multiview/same_scene.py",
           "out[v] = (motion_correlation(shared[0], shared[1], offsets[v]), shared[2])",
           "out[v] = (motion_correlation(shared[0], shared[1], -offsets[v]), shared[2])",
           ("tests/test_sync.py::test_motion_agreement_is_read_at_each_views_offset",)),
    # ---- association across views -------------------------------------------------------------
    Mutant("association: the calibrated pair gate opened", "posecam/multiview/associate.py",
           "        if c > ASSOCIATION.max_pair_angle:\n            break", "        if False:\n            break",
           ("tests/test_association.py::test_people_each_camera_alone_sees_are_not_one_person_through_a_calibration",)),
    Mutant("association: the consensus counts frames, not how well they fit", "posecam/multiview/associate.py",
           "return float(np.sum(np.diff(bounds) * (residual / ASSOCIATION.max_pair_angle - 1.0)))",
           "return -float(np.sum(np.diff(bounds)))",
           ("tests/test_association.py::test_two_people_are_told_apart_without_a_calibration",)),
    Mutant("association: the epipolar fit's translation derivative sign flipped", "posecam/multiview/associate.py",
           "np.cross(q, de_dl) @ dt]", "np.cross(de_dl, q) @ dt]",
           ("tests/test_association.py::test_the_epipolar_fit_s_derivatives_are_the_residuals_own",)),
    Mutant("association: a view's tracks that overlap in time joined", "posecam/multiview/associate.py",
           "if any(x.view == y.view and _overlap(x, y) > ASSOCIATION.max_shared for x in ga for y in gb):", "if False:",
           (f"{FUSION}::test_two_people_with_calibration_are_never_mixed",)),
    # ---- the calibration's gate -----------------------------------------------------------------
    Mutant("self-calibration: the scale from every person's bones", "posecam/multiview/calibrate.py",
           "scale_frames=frames if tallest is not None else None)", "scale_frames=None)",
           ("tests/test_consensus.py::test_the_scale_comes_from_the_tallest_persons_bones",)),
    Mutant("self-calibration: the scale from the shortest person's bones", "posecam/multiview/calibrate.py",
           "tallest = max(statures, key=statures.get) if statures else None",
           "tallest = min(statures, key=statures.get) if statures else None",
           ("tests/test_consensus.py::test_the_scale_comes_from_the_tallest_persons_bones",)),
    Mutant("calibration gate: a camera the bootstrap leaves loose kept", "posecam/multiview/calibrate.py",
           "if v != reference and not boot <= CALIBRATION.max_boot_rotation_deg:", "if False:",
           ("tests/test_spreads.py::test_a_camera_whose_spread_says_it_is_not_pinned_is_kept_marked_and_warned_about",
            "tests/test_spreads.py::test_fewer_than_two_cameras_left_is_a_refusal")),
    Mutant("calibration gate: a camera's reprojection error not compared", "posecam/multiview/calibrate.py",
           "elif not np.isfinite(errors[i]) or errors[i] > CALIBRATION.max_error_px:",
           "elif not np.isfinite(errors[i]):",
           ("tests/test_camera_gate.py::test_a_camera_that_tilted_as_it_filmed_is_dropped_for_its_reprojection_error",)),
    Mutant("calibration gate: a camera beside another kept", "posecam/multiview/policy.py",
           "min_ray_angle_deg: float = 8.0", "min_ray_angle_deg: float = 0.0",
           ("tests/test_camera_gate.py::test_a_camera_beside_another_is_dropped_for_its_geometry",)),
    Mutant("calibration: the bootstrap's spreads not widened by the keypoints' bias", "posecam/multiview/policy.py",
           "bias_floor: float = 1.0", "bias_floor: float = 0.0",
           ("tests/test_spreads.py::test_the_floor_widens_rotation_and_position_but_not_the_reference_nor_a_held_lens",)),
    # ---- left and right -------------------------------------------------------------------------
    Mutant("left/right: the 3D pose not swapped back with the keypoints", "posecam/multiview/left_right.py",
           "uv[v, f], xyz[v, f], conf[v, f] = uv[v, f][:, flip], xyz[v, f][:, flip], conf[v, f][:, flip]",
           "uv[v, f], conf[v, f] = uv[v, f][:, flip], conf[v, f][:, flip]",
           (f"{FUSION}::test_a_swap_undone_exchanges_the_monocular_pose_with_the_keypoints",)),
    Mutant("left/right: a swap taken for any gain", "posecam/multiview/left_right.py",
           "act = ratios[best, frames] < FUSION.swap_ratio", "act = ratios[best, frames] < 1.0",
           (f"{FUSION}::test_a_view_labelled_right_is_not_swapped_for_a_gain_its_noise_gives",)),
    # ---- re-identification ----------------------------------------------------------------------
    Mutant("re-identification: the looks' gate switched off", "posecam/tracking/reid.py",
           "    return unambiguous_pairs(cost, p.reid_distance, p.reid_margin)",
           "    return unambiguous_pairs(cost, np.inf, p.reid_margin)",
           (TRACKING,)),
    Mutant("re-identification: pairs out of the motion gate ranked among the looks' pairs", "posecam/tracking/policy.py",
           "out_of_gate: float = 1.0 ", "out_of_gate: float = 0.0 ",
           ("tests/test_reid_gate.py::test_no_pair_within_the_motion_gate_loses_to_one_out_of_it_whatever_the_looks",)),
    Mutant("re-identification: someone lost recognised whatever their clothes' colours", "posecam/tracking/policy.py",
           "reid_colour: float = 0.2 ", "reid_colour: float = 2.0 ",
           ("tests/test_reid_gate.py::test_a_man_of_his_shape_in_other_colours_is_not_him",)),
    Mutant("re-identification: a detection like two people lost takes the nearer's id", "posecam/tracking/policy.py",
           "reid_margin: float = 0.05 ", "reid_margin: float = 0.0 ",
           ("tests/test_reid_gate.py::test_a_detection_like_two_people_lost_by_a_hair_takes_neither_id",)),
    Mutant("re-identification: the looks forgotten with the motion", "posecam/tracking/policy.py",
           "reid_seconds: float = 10.0 ", "reid_seconds: float = 0.0 ",
           ("tests/test_embedder.py::test_the_looks_remember_people_ten_seconds_past_their_motion",)),
    Mutant("re-identification: a gallery of one look", "posecam/tracking/policy.py",
           "gallery: int = 8 ", "gallery: int = 1 ",
           ("tests/test_reid_gate.py::test_looks_taken_as_a_person_is_followed_bring_them_back_after_a_change",)),
    Mutant("re-identification: no look taken after a track's first", "posecam/tracking/policy.py",
           "refresh_every: int = 10 ", "refresh_every: int = 10**9 ",
           ("tests/test_reid_gate.py::test_looks_taken_as_a_person_is_followed_bring_them_back_after_a_change",)),
    # ---- the tracker -----------------------------------------------------------------------
    Mutant("tracker: matching-cost gate removed", "posecam/tracking/assignment.py",
           "if motion[i, j] <= max_cost and np.isfinite(cost[i, j])]", "if np.isfinite(cost[i, j])]",
           (f"{TRACKING}::test_a_track_is_not_matched_to_someone_who_does_not_overlap_it",)),
    Mutant("tracker: weak detections gated like confident ones", "posecam/tracking/tracker.py",
           "self._match(pool, low, p.low_match_cost, looks)", "self._match(pool, low, p.match_cost, looks)",
           (f"{TRACKING}::test_weak_detections_are_matched_under_a_tighter_gate",)),
    Mutant("tracker: the box filter has no velocity", "posecam/tracking/motion.py",
           "self.f[:4, 4:] = np.eye(4)", "self.f[:4, 4:] = 0.0",
           (f"{TRACKING}::test_a_track_moves_on_with_its_speed_while_unseen",)),
    Mutant("tracker: assignment of a tall matrix not transposed back", "posecam/tracking/assignment.py",
           "    if transposed:\n        rows, cols = cols, rows", "    if False:\n        rows, cols = cols, rows",
           (f"{TRACKING}::test_min_cost_assignment_matches_scipy_on_random_matrices",)),
    Mutant("tracker: a person followed turned loses their own crop to a box", "posecam/tracking/track.py",
           "self.own_roi = self.roi if followed and (turned or d.at_border) else None",
           "self.own_roi = self.roi if followed and d.at_border else None",
           ("tests/test_turned_views.py::test_a_person_followed_turned_keeps_their_own_crop_beside_a_detector_box",)),
    Mutant("tracker: a person the border cuts loses their own crop to a box", "posecam/tracking/track.py",
           "self.own_roi = self.roi if followed and (turned or d.at_border) else None",
           "self.own_roi = self.roi if followed and turned else None",
           ("tests/test_border_people.py::test_a_person_followed_at_the_border_keeps_their_own_crop_beside_a_detector_box",)),
    Mutant("detector: one person's overlapping boxes kept apart", "posecam/inference/policy.py",
           "merge_iou: float = 0.5 ", "merge_iou: float = 1.0 ",
           (f"{TRACKING}::test_the_search_finds_each_person_marked_by_hand_once_and_whole",)),
    Mutant("detector: one person's agreeing keypoints kept apart", "posecam/inference/policy.py",
           "merge_oks: float = 0.5 ", "merge_oks: float = 1.0 ",
           (f"{TRACKING}::test_the_search_finds_each_person_marked_by_hand_once_and_whole",)),
    Mutant("detector: a tile's detection cut by the tile's edge kept", "posecam/inference/policy.py",
           "tile_edge: float = 0.01 ", "tile_edge: float = 0.0 ",
           (f"{TRACKING}::test_the_search_finds_each_person_marked_by_hand_once_and_whole",)),
    Mutant("crop: a body crop sized by the torso alone", "posecam/inference/policy.py",
           "reach_margin: float = 1.0 ", "reach_margin: float = 0.0 ",
           ("tests/test_roi.py::test_body_roi_holds_arms_raised_above_the_head",)),
    Mutant("crop: a body crop far larger than its box kept", "posecam/inference/policy.py",
           "max_box_ratio: float = 1.6 ", "max_box_ratio: float = 1e9 ",
           ("tests/test_roi.py::test_the_crop_of_someone_the_border_cuts_at_the_hips_is_about_the_part_in_view",)),
    Mutant("detector: nobody marked at the border", "posecam/inference/detector.py",
           "score=min(1.0, d.score / DETECTION.border_score), at_border=True)",
           "score=min(1.0, d.score / DETECTION.border_score))",
           ("tests/test_border_people.py::test_the_detector_marks_the_people_the_border_may_cut",)),
    Mutant("pose: a frame at dusk posed in the dark", "posecam/estimate.py",
           "image_rgb = equalised(image_rgb) if under_exposed(image_rgb) else image_rgb", "pass",
           ("tests/test_dark_people.py::test_a_video_filmed_at_dusk_is_posed_in_its_light_equalised",)),
    Mutant("tracker: only people upside down keep their own crop", "posecam/tracking/policy.py",
           "turned: float = np.pi / 3 ", "turned: float = 2 * np.pi / 3 ",
           ("tests/test_turned_views.py::test_a_video_filmed_upside_down_or_sideways_gives_the_upright_skeletons",)),
    Mutant("tracker: a person lost is not looked for again", "posecam/tracking/tracker.py",
           "if t.number is None or not 0 < t.lost <= self.policy.probe_frames or t.seen_box is None:",
           "if True:",
           ("tests/test_lost_people.py::test_someone_hidden_then_in_the_dark_keeps_their_id",)),
    Mutant("tracker: a lost person looked for over someone followed", "posecam/tracking/tracker.py",
           " or any(boxes_overlap(t.box, b) for b in followed):", ":",
           ("tests/test_lost_people.py::test_no_probe_for_the_unconfirmed_the_long_lost_those_who_left_or_over_someone_followed",)),
    Mutant("tracker: a probe's pose over someone kept takes their place", "posecam/tracking/tracker.py",
           "            if not found[i] or over or", "            if not found[i] or",
           ("tests/test_lost_people.py::test_a_probe_whose_pose_lands_on_someone_kept_gives_way",)),
    Mutant("tracker: a strip the border leaves of a search region searched", "posecam/tracking/policy.py",
           "min_region_px: int = 16 ", "min_region_px: int = 0 ",
           (f"{TRACKING}::test_no_search_about_someone_lost_past_the_border",)),
    Mutant("tracker: a joint beside its own taken for a neighbour's", "posecam/tracking/policy.py",
           "foreign_off: float = 0.1 ", "foreign_off: float = 0.0 ",
           (f"{TRACKING}::test_joints_on_a_neighbour_are_found",)),
    # ---- the doubts -----------------------------------------------------------------------------
    Mutant("doubts: the root tested votes for its own steady path", "posecam/analysis/doubts.py",
           "(times <= time + self.window + 1e-6) & others", "(times <= time + self.window + 1e-6)",
           ("tests/test_doubts.py::test_a_root_is_tested_against_a_path_drawn_without_it",)),
    Mutant("doubts: a skeleton off its body not doubted", "posecam/analysis/doubts.py",
           "OFF_BODY = 0.11 ", "OFF_BODY = 10.0 ",
           ("tests/test_doubts.py::test_a_body_cut_by_the_border_and_seen_from_behind_is_off_body",)),
    # ---- left and right along a track -----------------------------------------------------------
    Mutant("sides: every frame as the pose model labels it", "posecam/analysis/sides.py",
           "        if entry.doubted or not track.given:\n", "        if True:\n",
           ("tests/test_sides.py::test_the_frames_the_lab_sees_swapped_are_relabelled_and_no_other",)),
    Mutant("sides: a track relabelled however much it moves", "posecam/analysis/sides.py",
           "STEP_OF_APART = 0.2\n", "STEP_OF_APART = 10.0\n",
           ("tests/test_sides.py::test_pedestrians_at_ten_frames_a_second_are_left_as_labelled",)),
    Mutant("judge: someone lost looked for again at --min-presence", "posecam/estimate.py",
           "max(self.options.min_presence, POLICY.probe_presence)", "self.options.min_presence",
           ("tests/test_lost_people.py::test_a_look_again_that_finds_only_a_doubted_pose_does_not_take_it",)),
    Mutant("judge: a doubted pose the detector's keypoints agree with dropped", "posecam/estimate.py",
           'return c, None if c.score >= min_presence or agrees else "presence"',
           'return c, None if c.score >= min_presence else "presence"',
           ("tests/test_judge.py::test_a_doubted_pose_the_detector_agrees_with_is_kept",)),
    Mutant("judge: a pose on a neighbour's joints never tried again", "posecam/estimate.py",
           "foreign.sum() < POLICY.retry_foreign_joints", "True",
           ("tests/test_judge.py::test_a_pose_on_the_neighbour_is_posed_again_from_another_crop",)),
    Mutant("sides: the stage left out of predict's chain", "posecam/estimate.py",
           "        frames = self._sided(frames)\n", "",
           ("tests/test_sides.py::test_predict_gives_the_labs_sides_on_a_clip_the_pose_model_swaps",)),
    # ---- what the pose model did not see --------------------------------------------------------
    Mutant("unseen: the hips seen without a knee", "posecam/results.py",
           "        if not seen[self._joints_of(KNEE_ROLES)].any():\n", "        if False:\n",
           ("tests/test_unseen.py::test_joints_off_the_picture_or_invented_are_unseen_in_the_json",)),
    Mutant("unseen: a joint off the picture seen", "posecam/results.py",
           "            seen &= (u >= 0) & (u < width) & (v >= 0) & (v < height)\n", "            pass\n",
           ("tests/test_unseen.py::test_joints_off_the_picture_or_invented_are_unseen_in_the_json",)),
    Mutant("intrinsics: a photo's assumed lens not warned of", "posecam/io/intrinsics.py",
           "        return _assumed_for_photo(image_path, width, height)\n", "",
           ("tests/test_unseen.py::test_a_photo_without_exif_or_lens_warns_once_that_the_lens_is_assumed",)),
    # ---- views lined up by given offsets --------------------------------------------------------
    Mutant("fuse: frames shared at given offsets counted from the wrong side", "posecam/multiview/take_check.py",
           "max(0.0, o_ref - o)", "max(0.0, o - o_ref)",
           ("tests/test_views.py::test_offsets_given_line_up_views_of_different_lengths",)),
    Mutant("fuse: a view a calibration does not fit left out unsaid", "posecam/multiview/fuse.py",
           " + unmatched_views(take, association)", "",
           ("tests/test_turned_views.py::test_a_view_the_calibration_does_not_fit_is_named",)),
    # ---- what fusion estimates from ---------------------------------------------------------------
    Mutant("observations: the take read from the smoothed keypoints", "posecam/multiview/observations.py",
           "uv[rows], xyz[rows], conf[rows] = t.observed_2d[sound], t.observed_3d[sound], t.confidence[sound]",
           "uv[rows], xyz[rows], conf[rows] = t.keypoints_2d[sound], t.keypoints_3d[sound], t.confidence[sound]",
           ("tests/test_fuse_cmd.py::test_fusing_videos_is_fusing_the_pose_files_predict_writes_of_them",)),
    Mutant("observations: a joint glimpsed in a few frames low-passed as if followed", "posecam/multiview/policy.py",
           "lowpass_frames: int = 15", "lowpass_frames: int = 2",
           ("tests/test_sync.py::test_a_joint_glimpsed_in_a_few_frames_gives_no_motion",)),
    Mutant("pose files: the observed keypoints not written", "posecam/io/poses.py",
           "    if p.observed_2d is not None:         #", "    if False:         #",
           ("tests/test_fuse_cmd.py::test_fusing_videos_is_fusing_the_pose_files_predict_writes_of_them",)),
    # ---- a session of takes -------------------------------------------------------------------------
    Mutant("session: a camera the takes place differently kept in them all", "posecam/multiview/session.py",
           "inliers = [i for i, r in enumerate(qs) if turned(best, r) <= within]", "inliers = list(range(len(qs)))",
           ("tests/test_session.py::test_own_rigs_that_place_a_camera_differently_disagree_on_it",
            "tests/test_session.py::test_a_camera_misnamed_in_one_take_is_named_and_left_out")),
    Mutant("session: the rig left in its first camera's frame", "posecam/multiview/world.py",
           "    moved = world.rig(rig)\n", "    moved = rig\n",
           ("tests/test_session.py::test_the_session_rig_matches_the_cameras_and_stands_on_the_floor",)),
    Mutant("fuse: a take fused through an unsynchronised rig at offset 0", "posecam/multiview/options.py",
           "return self.calibration is not None and self.calibration.synchronised",
           "return self.calibration is not None",
           ("tests/test_session.py::test_each_take_keeps_its_own_offsets_and_fuses_through_the_rig",)),
    Mutant("fuse: a take in which nobody moves synchronised anyway", "posecam/multiview/fuse.py",
           "still = opts.sync and holds_still(take, opts.min_conf)", "still = False",
           ("tests/test_session.py::test_a_still_take_joins_the_session_and_alone_is_refused_with_what_helps",)),
)


# The test files of each stage's modules, by the start of the mutated file's path: a mutant runs
# all of them (first match wins).
MULTIVIEW = (CONSENSUS, FUSION, "tests/test_schur_lm.py", "tests/test_sync.py", "tests/test_association.py",
             "tests/test_spreads.py", "tests/test_camera_gate.py", "tests/test_views.py", "tests/test_fuse_cmd.py",
             "tests/test_turned_views.py", "tests/test_session.py")
STAGES = (
    ("posecam/geometry/lift.py", (CAMERA, "tests/test_predict.py")),
    ("posecam/geometry/camera.py", (CAMERA, CALIB)),
    ("posecam/io/calibration.py", (CALIB,)),
    ("posecam/io/validate.py", (CALIB,)),
    ("posecam/io/intrinsics.py", ("tests/test_intrinsics.py",)),
    ("posecam/io/poses.py", ("tests/test_pose_files.py", "tests/test_fuse_cmd.py")),
    ("posecam/scale/", (METRIC, "tests/test_heights.py", "tests/test_depth_spread.py")),
    ("posecam/multiview/", MULTIVIEW),
    ("posecam/tracking/", (TRACKING, "tests/test_embedder.py", "tests/test_reid.py", "tests/test_reid_gate.py",
                           "tests/test_turned_views.py", "tests/test_lost_people.py")),
    ("posecam/analysis/doubts.py", ("tests/test_doubts.py",)),
    ("posecam/analysis/sides.py", ("tests/test_sides.py",)),
)


def stage_tests(m: Mutant) -> tuple[str, ...]:
    """The test files a mutant runs: its stage's (those that exist) and those of the tests it names."""
    stage = next((files for prefix, files in STAGES if m.file.startswith(prefix)), ())
    files = [f for f in stage if (ROOT / f).exists()] + [t.split("::")[0] for t in m.tests]
    return tuple(dict.fromkeys(files))


def _check_snippets(mutants: tuple[Mutant, ...]) -> list[str]:
    """One line per mutant whose snippet is not found exactly once."""
    problems = []
    for m in mutants:
        path = ROOT / m.file
        count = path.read_text().count(m.original) if path.exists() else -1
        if count != 1:
            where = "file missing" if count < 0 else f"found {count} times"
            problems.append(f"{m.name}: snippet in {m.file} {where} (update the table in tests/mutants.py)")
    return problems


def _copy(dest: Path, mutant: Mutant | None) -> None:
    """posecam/ into dest (its models linked), with the mutant's replacement applied."""
    shutil.copytree(ROOT / "posecam", dest / "posecam", ignore=shutil.ignore_patterns("__pycache__", "models"))
    (dest / "posecam" / "models").symlink_to(ROOT / "posecam" / "models")
    if mutant is not None:
        path = dest / mutant.file
        path.write_text(path.read_text().replace(mutant.original, mutant.replacement, 1))


@dataclass
class Outcome:
    code: int                   # pytest's exit status; -1: timed out
    killer: dict | None         # the first test that failed on an assertion: {"test", "line"}
    last: str                   # pytest's last line of interest
    seconds: float


def _pytest(copy: Path, files: tuple[str, ...], first: tuple[str, ...], plugin_dir: Path,
            timeout: float = TIMEOUT_S) -> Outcome:
    """Run the test files against the copy (run from it: the copy comes first on the path, for
    the subprocesses the tests start too), the `first` tests first, with the verdict plugin."""
    verdict = copy / "verdict.json"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(copy), str(plugin_dir), str(ROOT)]),
           "PYTHONDONTWRITEBYTECODE": "1", "MUTANT_FIRST": json.dumps(list(first)), "MUTANT_VERDICT": str(verdict)}
    args = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", PLUGIN, "--rootdir", str(ROOT),
            "-c", str(ROOT / "pyproject.toml"), *(str(ROOT / t) for t in files)]
    start = time.monotonic()
    try:
        run = subprocess.run(args, cwd=copy, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return Outcome(-1, None, f"timed out after {timeout:.0f} s", time.monotonic() - start)
    lines = [ln for ln in run.stdout.splitlines() if ln.startswith(("FAILED", "ERROR"))] or run.stdout.splitlines()[-1:]
    last = lines[0] if lines else run.stderr.strip()[-200:]
    killer = json.loads(verdict.read_text()) if verdict.exists() else None
    return Outcome(run.returncode, killer, last, time.monotonic() - start)


def _imports_the_copy(copy: Path) -> bool:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(copy), str(ROOT)])}
    out = subprocess.run([sys.executable, "-c", "import posecam; print(posecam.__file__)"], cwd=copy, env=env,
                         capture_output=True, text=True)
    return Path(out.stdout.strip()).resolve().is_relative_to(copy.resolve())


def _verdict(o: Outcome) -> str:
    if o.killer is not None:
        return "killed"
    return {0: "SURVIVED", NO_TESTS: "NO TESTS", -1: "TIMEOUT"}.get(o.code, "CRASHED")


def run(mutants: tuple[Mutant, ...], jobs: int) -> int:
    problems = _check_snippets(mutants)
    for p in problems:
        print(f"MISSING  {p}", file=sys.stderr)
    live = [m for m in mutants if not any(p.startswith(f"{m.name}:") for p in problems)]
    with tempfile.TemporaryDirectory(prefix="posecam-mutants-") as tmp:
        (Path(tmp) / f"{PLUGIN}.py").write_text(PLUGIN_SOURCE)
        base = Path(tmp) / "unmutated"
        _copy(base, None)
        if not _imports_the_copy(base):
            print("the copy of posecam is not the one imported: check PYTHONPATH", file=sys.stderr)
            return 1
        files = tuple(dict.fromkeys(f for m in live for f in stage_tests(m)))
        named = tuple(dict.fromkeys(t for m in live for t in m.tests))
        o = _pytest(base, files, named, Path(tmp), 3 * TIMEOUT_S)
        print(f"unmutated: {len(files)} test files {'pass' if o.code == 0 else 'FAIL'} ({o.seconds:.0f} s)")
        missing = [t for t in named if "::" in t and t.split("::")[1].split("[")[0] not in
                   (ROOT / t.split("::")[0]).read_text()]
        if o.code != 0 or missing:
            print(f"  {o.last}" if o.code != 0 else f"  tests named but not found: {', '.join(missing)}",
                  file=sys.stderr)
            return 1

        def one(i_m: tuple[int, Mutant]) -> tuple[Mutant, Outcome]:
            i, m = i_m
            copy = Path(tmp) / f"m{i}"
            _copy(copy, m)
            outcome = _pytest(copy, stage_tests(m), m.tests, Path(tmp))
            shutil.rmtree(copy, ignore_errors=True)
            return m, outcome

        with ThreadPoolExecutor(max_workers=jobs) as pool:
            results = list(pool.map(one, enumerate(live)))
    width = max(len(m.name) for m in mutants)
    print(f"\n{'mutant':<{width}}  {'result':<8}  {'s':>4}  caught by")
    survived = 0
    for m, o in results:
        verdict = _verdict(o)
        survived += verdict != "killed"
        why = o.killer["test"] if o.killer else o.last if verdict != "SURVIVED" else ", ".join(stage_tests(m))
        print(f"{m.name:<{width}}  {verdict:<8}  {o.seconds:4.0f}  {why}")
    print(f"\n{len(results) - survived} killed, {survived} not killed, {len(problems)} snippets missing")
    return 1 if survived or problems else 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--jobs", type=int, default=2, help="mutants tested at once (default 2)")
    parser.add_argument("-k", default="", help="only the mutants whose name contains this")
    parser.add_argument("--list", action="store_true", help="list the mutants and exit")
    args = parser.parse_args()
    chosen = tuple(m for m in MUTANTS if args.k in m.name)
    if args.list:
        for m in chosen:
            print(f"{m.name}  [{m.file}]  <- {', '.join(stage_tests(m))}")
        return
    sys.exit(run(chosen, max(1, args.jobs)))


if __name__ == "__main__":
    main()
