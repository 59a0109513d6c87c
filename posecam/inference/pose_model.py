"""Pose models and their lifters, for both depth kinds of the model contract: a pose model
turns crops into 2D joints and the model's 3D output, which does not depend on the lens; its
kind's lifter places that output in camera space through a lens (`make_lifter`).

- `LandmarkPoseModel` (kind "landmarks", BlazePose GHUM 3D): 2D landmarks in the crop plus a
  metric root-relative pose; its lifter solves the root translation from the pinhole model.
- `RootDepthPoseModel` (kind "root_depth", the paper's ResNet-U): (u, v), relative depth d_i
  and absolute root depth z_a; its lifter: z_i = d_i + z_a, then back-projection (paper eq. 3).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from posecam.geometry.camera import Intrinsics
from posecam.geometry.lift import back_project, place_on_keypoints
from posecam.geometry.triangulate import MIN_CONFIDENCE
from posecam.inference.roi import Roi
from posecam.inference.contract import ModelContract
from posecam.inference.session import Model, to_input_tensor


@dataclass
class PoseCandidate:
    """One person's pose in the joints of the model that produced it, before the lift."""

    score: float                # presence of a person in the ROI, [0, 1]
    keypoints_2d: np.ndarray    # (J, 2) image pixels
    relative: np.ndarray        # the model's 3D output, mm about the root: (J, 3) the metric pose in the
                                # image's axes (landmarks), or (J,) the depths d_i (root_depth)
    confidence: np.ndarray      # (J,) [0, 1]
    next_roi: Roi               # where to look for this person in the next frame
    root_depth: float = float("nan")   # root_depth: z_a (mm) for the training camera's lens


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-np.clip(x, -80, 80)))


class _CropModel:
    """Shared crop + run: batches ROIs when the model's batch axis is dynamic."""

    def __init__(self, model: Model):
        self.model = model
        self.contract = model.contract
        self.size = int(self.contract.input.size[0])
        self.joints = self.contract.joints

    def _run(self, image_rgb: np.ndarray, rois: list[Roi], extra: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        crops = np.stack([roi.crop(image_rgb, self.size) for roi in rois])
        x = to_input_tensor(crops, self.contract.input)
        feeds = {self.contract.input.name: x, **(extra or {})}
        if self.model.batch_dynamic or len(rois) == 1:
            return self.model.run(feeds)
        parts = [self.model.run({k: v[i:i + 1] for k, v in feeds.items()}) for i in range(len(rois))]
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


class LandmarkPoseModel(_CropModel):
    """BlazePose GHUM 3D: 33 landmarks (+ 6 ROI helpers) and metric world landmarks."""

    def __call__(self, image_rgb: np.ndarray, rois: list[Roi]) -> list[PoseCandidate]:
        out = self._run(image_rgb, rois)
        n_joints = len(self.joints)
        points = out["landmarks"].shape[-1] // 5   # the joints, then ROI helpers (at least 2)
        self.model.check_shapes(out, {"landmarks": (len(rois), 5 * max(points, n_joints + 2)),
                                      "presence": (len(rois), 1), "world": (len(rois), 3 * points)})
        landmarks = out["landmarks"].reshape(len(rois), -1, 5).astype(np.float64)
        world = out["world"].reshape(len(rois), -1, 3)[:, :n_joints].astype(np.float64) * 1000.0
        presence = out["presence"].reshape(len(rois)).astype(np.float64)
        result = []
        for roi, lm, rel, score in zip(rois, landmarks, world, presence):
            uv = roi.to_image(lm[:, :2], self.size)
            conf = _sigmoid(lm[:n_joints, 3]) * _sigmoid(lm[:n_joints, 4])
            result.append(PoseCandidate(
                float(score), uv[:n_joints], roi.rotate_to_image(rel), conf,   # world landmarks: the crop's axes
                # landmarks 33, 34: hip centre and full-body scale point, as for the detector
                Roi.from_alignment_points(uv[n_joints], uv[n_joints + 1]),
            ))
        return result


class RootDepthPoseModel(_CropModel):
    """The paper's ResNet-U: (u, v, d) per joint, z_a per person, confidence per joint."""

    def __call__(self, image_rgb: np.ndarray, rois: list[Roi]) -> list[PoseCandidate]:
        h, w = image_rgb.shape[:2]
        rois = [Roi(r.cx, r.cy, r.size) for r in rois]  # ResNet-U crops are upright
        boxes = np.array([[r.cx / w, r.cy / h, r.size / w, r.size / h] for r in rois], np.float32)
        out = self._run(image_rgb, rois, {self.contract.box_input: boxes})
        n, j = len(rois), len(self.joints)
        self.model.check_shapes(out, {"uv": (n, j, 2), "depth": (n, j), "z_root": (n, 1), "confidence": (n, j)})
        result = []
        for i, roi in enumerate(rois):
            uv = roi.to_image(out["uv"][i].astype(np.float64), self.size)
            conf = np.clip(out["confidence"][i].astype(np.float64), 0.0, 1.0)
            confident = uv[conf >= MIN_CONFIDENCE] if (conf >= MIN_CONFIDENCE).sum() >= 2 else uv
            result.append(PoseCandidate(
                float(conf.mean()), uv, out["depth"][i].astype(np.float64), conf, Roi.around_points(confident),
                float(out["z_root"][i, 0]),
            ))
        return result


def make_pose_model(model: Model) -> LandmarkPoseModel | RootDepthPoseModel:
    if model.contract.kind == "landmarks":
        return LandmarkPoseModel(model)
    return RootDepthPoseModel(model)


def make_lifter(contract: ModelContract) -> Callable[[PoseCandidate, Intrinsics, int], np.ndarray]:
    """The lifter of a pose model's kind (its contract says which): (candidate, lens, image width)
    -> (J, 3) camera points. Kind "landmarks": the metric root-relative pose placed on its 2D
    keypoints through the lens (the root translation in weighted least squares, the joints'
    confidences the weights). Kind "root_depth": z_i = d_i + z_a, z_a rescaled from the training
    camera's lens to this one by the focal length in image widths (z_a was learned for one
    camera), then each joint back-projected (paper eq. 3)."""
    if contract.kind == "landmarks":
        return lambda c, k, width: place_on_keypoints(c.relative, c.keypoints_2d, c.confidence, k)
    train_focal_widths = contract.train_focal / contract.train_image_width

    def lift(c: PoseCandidate, k: Intrinsics, width: int) -> np.ndarray:
        f_ratio = ((k.fx + k.fy) / 2 / width) / train_focal_widths
        return back_project(c.keypoints_2d, c.relative + c.root_depth * f_ratio, k)
    return lift
