"""Training samples from a manifest (see MANIFEST.md), cropped and augmented as in the paper.

Augmentations (paper section 5.2): rotation +-30 deg, re-scaling 0.7..1.3, horizontal flip
with left/right joints swapped, colour gains 0.9..1.1, black occlusion boxes, and jittered
box position. Crops are squares around the box, as the runtime's detector ROIs are.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import torch

from export.convert.onnx_export import IMAGENET_MEAN, IMAGENET_STD
from posecam.inference.contract import InputSpec
from posecam.errors import InputError
from posecam.inference.roi import ROI_SCALE, Roi
from posecam.inference.session import to_input_tensor
from posecam.skeleton import H36M


@dataclass(frozen=True)
class Sample:
    image: Path                 # absolute path
    box: np.ndarray             # (4,) x0, y0, x1, y1 px
    joints: np.ndarray          # (17, 3) camera coordinates, mm
    fx: float
    fy: float
    cx: float
    cy: float


def read_manifest(path: str | os.PathLike) -> list[Sample]:
    """Parse a JSON-lines manifest; InputError naming the line for anything malformed."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"manifest {path} does not exist")
    samples = []
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip():
            continue
        try:
            d = json.loads(line)
            k = d["intrinsics"]
            s = Sample(path.parent / d["image"], np.asarray(d["box"], float), np.asarray(d["joints"], float),
                       float(k["fx"]), float(k["fy"]), float(k["cx"]), float(k["cy"]))
        except (ValueError, KeyError, TypeError) as exc:
            raise InputError(f"{path}:{n}: malformed manifest line ({exc!r})") from None
        if s.box.shape != (4,) or s.joints.shape != (len(H36M.joints), 3) or not np.isfinite(s.joints).all():
            raise InputError(f"{path}:{n}: needs a box [x0, y0, x1, y1] and {len(H36M.joints)} finite [x, y, z] joints")
        if (s.joints[:, 2] <= 0).any():
            raise InputError(f"{path}:{n}: joints must be in front of the camera (z > 0 mm)")
        if not s.image.is_file():
            raise InputError(f"{path}:{n}: image {s.image} does not exist")
        samples.append(s)
    if not samples:
        raise InputError(f"manifest {path} holds no sample")
    return samples


@dataclass
class Augment:
    rotation_deg: float = 30.0
    scale: tuple[float, float] = (0.7, 1.3)
    shift: float = 0.1            # box centre jitter, fraction of the crop side
    flip: float = 0.5             # probability
    gain: tuple[float, float] = (0.9, 1.1)
    occlusion: float = 0.5        # probability of one black box


NO_AUGMENT = Augment(0.0, (1.0, 1.0), 0.0, 0.0, (1.0, 1.0), 0.0)
_SPEC = InputSpec("image", "NCHW", (0, 0), IMAGENET_MEAN, IMAGENET_STD)


class PoseDataset(torch.utils.data.Dataset):
    """Items: image [3,S,S], box [4], uv [J,2] crop px, depth [J] mm, z_root [1] mm.

    z_root is expressed for the training camera: divided by (f / W) / (train_focal / train_width),
    the factor the runtime multiplies it by, so manifests may mix cameras.
    """

    def __init__(self, samples: list[Sample], input_size: int, train_focal: float, train_width: float,
                 augment: Augment = NO_AUGMENT, seed: int = 0):
        self.samples, self.size, self.augment = samples, input_size, augment
        self.train_ratio = train_focal / train_width
        self.rng = np.random.default_rng(seed)
        self.flip = H36M.flip_indices
        self.root = H36M.index(H36M.root)

    def __len__(self) -> int:
        return len(self.samples)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        s, a, rng, size = self.samples[i], self.augment, self.rng, self.size
        bgr = cv2.imread(str(s.image), cv2.IMREAD_COLOR)
        if bgr is None:
            raise InputError(f"cannot read image {s.image}")
        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        h, w = rgb.shape[:2]
        side = float(max(s.box[2] - s.box[0], s.box[3] - s.box[1])) * ROI_SCALE * rng.uniform(*a.scale)
        cx, cy = (s.box[:2] + s.box[2:]) / 2 + rng.uniform(-a.shift, a.shift, 2) * side
        upright = Roi(float(cx), float(cy), side)
        roi = Roi(upright.cx, upright.cy, side, np.deg2rad(rng.uniform(-a.rotation_deg, a.rotation_deg)))
        crop = roi.crop(rgb, size).astype(np.float32)
        uv_img = np.stack([s.fx * s.joints[:, 0] / s.joints[:, 2] + s.cx,
                           s.fy * s.joints[:, 1] / s.joints[:, 2] + s.cy], axis=-1)
        m = roi.crop_matrix(size)
        uv = uv_img @ m[:, :2].T + m[:, 2]
        depth = s.joints[:, 2] - s.joints[self.root, 2]
        box = np.array([cx / w, cy / h, side / w, side / h])
        if rng.random() < a.flip:
            crop = crop[:, ::-1]
            uv = np.stack([size - 1 - uv[:, 0], uv[:, 1]], axis=-1)[self.flip]
            depth = depth[self.flip]
            box[0] = 1.0 - box[0]
        crop = crop * rng.uniform(*a.gain, 3)
        if rng.random() < a.occlusion:
            bw, bh = rng.uniform(0.1, 0.4, 2) * size
            x0, y0 = rng.uniform(0, size - bw), rng.uniform(0, size - bh)
            crop[int(y0):int(y0 + bh), int(x0):int(x0 + bw)] = 0
        crop = np.clip(crop, 0, 255).astype(np.uint8)
        f_ratio = ((s.fx + s.fy) / 2 / w) / self.train_ratio
        return {
            "image": torch.from_numpy(to_input_tensor(crop[None], _SPEC)[0]),
            "box": torch.tensor(box, dtype=torch.float32),
            "uv": torch.tensor(uv, dtype=torch.float32),
            "depth": torch.tensor(depth, dtype=torch.float32),
            "z_root": torch.tensor([s.joints[self.root, 2] / f_ratio], dtype=torch.float32),
        }


def camera_of(samples: list[Sample]) -> tuple[float, float]:
    """(focal px, image width px) of the manifest's typical camera: medians over up to 50 samples."""
    samples = samples[::max(1, len(samples) // 50)]
    widths = []
    for s in samples:
        img = cv2.imread(str(s.image), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise InputError(f"cannot read image {s.image}")
        widths.append(img.shape[1])
    return float(np.median([(s.fx + s.fy) / 2 for s in samples])), float(np.median(widths))
