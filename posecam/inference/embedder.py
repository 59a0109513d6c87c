"""Appearance vectors of people's boxes, for re-identifying them (an "embedder" model).

Each box is stretched to the model's input (a portrait crop; a standing person fills it) and
the model gives one unit vector per crop; a classic complement is appended: the colours of
the upper and the lower body (HSV histograms of the crop's middle, square-rooted, so that
their dot product is the Bhattacharyya coefficient), which tell apart people whose ImageNet
features are alike. 1 - a . b is the cosine distance of two people's looks: the share
`COLOUR_SHARE` of it from the colours, the rest from the network.
"""

from __future__ import annotations

import cv2
import numpy as np

from posecam.inference.session import Model, load_model, to_input_tensor

DEFAULT_EMBEDDER = "mobilenetv2"
COLOUR_SHARE = 0.5
HSV_BINS = (8, 3, 3)                            # hue, saturation, value
BODY_PARTS = ((0.15, 0.5), (0.5, 0.9))          # upper and lower body: rows of the crop (fractions)
MIDDLE = (0.2, 0.8)                             # columns of the crop (the background left out)


def colour_histograms(crops: np.ndarray) -> np.ndarray:
    """(N, H, W, 3) uint8 RGB portrait crops -> (N, 2 * prod(HSV_BINS)) unit vectors: the
    square roots of the normalised HSV histograms of the upper and the lower body."""
    n, h, w = crops.shape[:3]
    cols = slice(int(MIDDLE[0] * w), int(MIDDLE[1] * w))
    out = np.empty((n, len(BODY_PARTS) * int(np.prod(HSV_BINS))), np.float32)
    for i, crop in enumerate(crops):
        hsv = cv2.cvtColor(crop, cv2.COLOR_RGB2HSV)
        parts = []
        for y0, y1 in BODY_PARTS:
            part = np.ascontiguousarray(hsv[int(y0 * h):int(y1 * h), cols])
            counts = cv2.calcHist([part], [0, 1, 2], None, list(HSV_BINS), [0, 180, 0, 256, 0, 256]).ravel()
            parts.append(np.sqrt(counts / max(counts.sum(), 1.0)))
        out[i] = np.concatenate(parts) / np.sqrt(len(BODY_PARTS))
    return out


def colour_distance(features: np.ndarray, others: np.ndarray) -> np.ndarray:
    """(N, M) cosine distance of the colour part alone of N and M appearance vectors."""
    n = len(BODY_PARTS) * int(np.prod(HSV_BINS))
    return 1.0 - (features[:, -n:] @ others[:, -n:].T) / COLOUR_SHARE


class AppearanceEmbedder:
    """(N, 4) boxes (x0, y0, x1, y1 px) of one RGB image -> (N, D) unit appearance vectors."""

    def __init__(self, model: Model):
        self.model = model
        self.height, self.width = model.contract.input.size

    def crops(self, image_rgb: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """(N, H, W, 3) uint8: each box stretched to the input size (outside the image: black)."""
        out = np.empty((len(boxes), self.height, self.width, 3), np.uint8)
        for i, (x0, y0, x1, y1) in enumerate(np.asarray(boxes, float)):
            sx, sy = self.width / max(x1 - x0, 1.0), self.height / max(y1 - y0, 1.0)
            m = np.array([[sx, 0.0, -sx * x0], [0.0, sy, -sy * y0]])
            out[i] = cv2.warpAffine(image_rgb, m, (self.width, self.height), flags=cv2.INTER_LINEAR,
                                    borderMode=cv2.BORDER_CONSTANT)
        return out

    def __call__(self, image_rgb: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        if not len(boxes):
            return np.zeros((0, 0), np.float32)
        spec = self.model.contract.input
        crops = self.crops(image_rgb, boxes)
        out = self.model.run({spec.name: to_input_tensor(crops, spec)})
        self.model.check_shapes(out, {"embedding": (len(boxes), None)})
        return np.hstack([np.sqrt(1 - COLOUR_SHARE) * out["embedding"], np.sqrt(COLOUR_SHARE) * colour_histograms(crops)])


def load_embedder(name_or_path: str = DEFAULT_EMBEDDER, threads: int | None = None,
                  device: str = "cpu") -> AppearanceEmbedder:
    """The bundled appearance embedder ("mobilenetv2") or a posecam embedder .onnx file."""
    return AppearanceEmbedder(load_model(name_or_path, threads, kind="embedder", device=device))
