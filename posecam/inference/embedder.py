"""Appearance vectors of people's boxes, for re-identifying them (an "embedder" model).

Each box is stretched to the model's input (a portrait crop; a standing person fills it) and
the model gives one unit vector per crop: 1 - a . b is the cosine distance of two people's looks.
"""

from __future__ import annotations

import cv2
import numpy as np

from posecam.inference.session import Model, load_model, to_input_tensor

DEFAULT_EMBEDDER = "mobilenetv2"


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
        x = to_input_tensor(self.crops(image_rgb, boxes), spec)
        out = self.model.run({spec.name: x})
        self.model.check_shapes(out, {"embedding": (len(boxes), None)})
        return out["embedding"]


def load_embedder(name_or_path: str = DEFAULT_EMBEDDER, threads: int | None = None,
                  device: str = "cpu") -> AppearanceEmbedder:
    """The bundled appearance embedder ("mobilenetv2") or a posecam embedder .onnx file."""
    return AppearanceEmbedder(load_model(name_or_path, threads, kind="embedder", device=device))
