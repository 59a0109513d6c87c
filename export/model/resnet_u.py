"""ResNet-U (paper section 3, Fig. 3): crop + box -> (u, v), relative depth, z_a, confidence.

    backbone (ResNet-50 to layer3, stride 16) ──► upsample to stride 8 (+ stride-8 skip)
        ──► U-blocks ──► per joint: heatmap logits and depth map
              heatmap h_i = softmax over pixels; (u_i, v_i) = soft-argmax(h_i)
              d_i = 1 m * sum h_i * tanh(depth map_i)              (eq. 1, a 2 m range)
    pooled backbone features ++ box (cx/W, cy/H, w/W, h/H) ──► FC 256, 256, 1 = alpha
              z_a = rho / (1 + exp(beta * alpha)), rho = 10 m, beta = 0.5  (eq. 2)
    pooled head features ++ heatmap peaks (detached) ──► FC ──► sigmoid: confidence
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import torch
import torch.nn.functional as F
from torch import nn

from export.model.backbones import BACKBONES, build_backbone
from posecam.errors import InputError
from posecam.skeleton import H36M_JOINTS

RHO_MM = 10_000.0          # eq. 2: maximum depth
BETA = 0.5                 # eq. 2: smoothing factor
DEPTH_RANGE_MM = 2_000.0   # eq. 1: relative depths span 2 m around the root
FC_UNITS = 256             # the z_a network's width


# Bounds on what a checkpoint's config may ask for (checkpoints are untrusted input).
MAX_INPUT_SIZE, MAX_HEAD_CHANNELS, MAX_U_BLOCKS, MAX_JOINTS = 1024, 1024, 8, 200


@dataclass
class ResNetUConfig:
    """Everything needed to rebuild a ResNet-U and interpret its outputs."""

    backbone: str = "resnet50"
    joints: tuple[str, ...] = H36M_JOINTS
    input_size: int = 256          # square crops; a multiple of 32
    head_channels: int = 256       # width of the U-blocks
    u_blocks: int = 2
    train_focal: float = 1145.0    # px, the training camera (default: Human3.6M's)
    train_image_width: float = 1000.0

    def __post_init__(self) -> None:
        self.joints = tuple(self.joints)
        if self.backbone not in BACKBONES:
            raise InputError(f"unknown backbone {self.backbone!r}; choose one of {', '.join(BACKBONES)}")
        if not 32 <= self.input_size <= MAX_INPUT_SIZE or self.input_size % 32:
            raise InputError(f"input size must be a multiple of 32 from 32 to {MAX_INPUT_SIZE}, got {self.input_size}")
        if not 8 <= self.head_channels <= MAX_HEAD_CHANNELS:
            raise InputError(f"head_channels must be from 8 to {MAX_HEAD_CHANNELS}, got {self.head_channels}")
        if not 1 <= self.u_blocks <= MAX_U_BLOCKS:
            raise InputError(f"u_blocks must be from 1 to {MAX_U_BLOCKS}, got {self.u_blocks}")
        if not 1 <= len(self.joints) <= MAX_JOINTS:
            raise InputError(f"a ResNet-U needs 1 to {MAX_JOINTS} joints, got {len(self.joints)}")
        if not (0 < self.train_focal < float("inf") and 0 < self.train_image_width < float("inf")):
            raise InputError("train_focal and train_image_width must be positive numbers")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["joints"] = list(self.joints)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "ResNetUConfig":
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise InputError(f"unknown ResNet-U config keys: {', '.join(sorted(unknown))}")
        return cls(**d)


class Residual(nn.Module):
    """Bottleneck residual unit at constant width."""

    def __init__(self, ch: int):
        super().__init__()
        mid = ch // 2
        self.body = nn.Sequential(
            nn.Conv2d(ch, mid, 1, bias=False), nn.BatchNorm2d(mid), nn.ReLU(inplace=True),
            nn.Conv2d(mid, mid, 3, 1, 1, bias=False), nn.BatchNorm2d(mid), nn.ReLU(inplace=True),
            nn.Conv2d(mid, ch, 1, bias=False), nn.BatchNorm2d(ch),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.relu(x + self.body(x))


class UBlock(nn.Module):
    """A small U-Net: two poolings down, two upsamplings back with skips, same resolution out."""

    def __init__(self, ch: int, levels: int = 2):
        super().__init__()
        self.down = nn.ModuleList(Residual(ch) for _ in range(levels + 1))
        self.up = nn.ModuleList(Residual(ch) for _ in range(levels))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        skips = []
        for i, block in enumerate(self.down):
            x = block(F.max_pool2d(x, 2) if i else x)
            skips.append(x)
        for block, skip in zip(self.up, reversed(skips[:-1])):
            x = block(skip + F.interpolate(x, scale_factor=2.0, mode="nearest"))
        return x


def _conv_bn_relu(cin: int, cout: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 1, bias=False), nn.BatchNorm2d(cout), nn.ReLU(inplace=True))


class ResNetU(nn.Module):
    """forward(image [N,3,S,S] ImageNet-normalised, box [N,4]) -> uv [N,J,2] crop px,
    depth [N,J] mm relative to the root, z_root [N,1] mm, confidence [N,J]."""

    def __init__(self, config: ResNetUConfig | None = None):
        super().__init__()
        self.config = c = config or ResNetUConfig()
        j, ch = len(c.joints), c.head_channels
        self.backbone = build_backbone(c.backbone)
        c8, c16 = self.backbone.channels
        self.lateral8 = _conv_bn_relu(c8, ch)
        self.lateral16 = _conv_bn_relu(c16, ch)
        self.ublocks = nn.Sequential(*(UBlock(ch) for _ in range(c.u_blocks)))
        self.heatmap = nn.Conv2d(ch, j, 1)
        self.depth_map = nn.Conv2d(ch, j, 1)
        self.root_depth = nn.Sequential(   # no BatchNorm1d: it rejects batch 1 in training
            nn.Linear(c16 + 4, FC_UNITS), nn.ReLU(inplace=True),
            nn.Linear(FC_UNITS, FC_UNITS), nn.ReLU(inplace=True),
            nn.Linear(FC_UNITS, 1),
        )
        self.confidence = nn.Sequential(nn.Linear(ch + j, FC_UNITS), nn.ReLU(inplace=True), nn.Linear(FC_UNITS, j))

    def heatmaps(self, image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """(heatmaps h [N,J,Hf,Wf] with unit sum, depth maps, head features, backbone features)."""
        s8, s16 = self.backbone(image)
        x = self.lateral8(s8) + F.interpolate(self.lateral16(s16), scale_factor=2.0, mode="nearest")
        x = self.ublocks(x)
        logits = self.heatmap(x)
        h = logits.flatten(2).softmax(-1).view_as(logits)
        return h, self.depth_map(x), x, s16

    def forward(self, image: torch.Tensor, box: torch.Tensor) -> tuple[torch.Tensor, ...]:
        h, dmap, x, s16 = self.heatmaps(image)
        hf, wf = h.shape[-2:]
        size = self.config.input_size
        # soft-argmax; pixel centres at integers, as OpenCV's warpAffine (and posecam.inference.roi) use them
        xs = (torch.arange(wf, dtype=h.dtype) + 0.5) * (size / wf) - 0.5
        ys = (torch.arange(hf, dtype=h.dtype) + 0.5) * (size / hf) - 0.5
        u = (h.sum(2) * xs).sum(-1)
        v = (h.sum(3) * ys).sum(-1)
        uv = torch.stack([u, v], dim=-1)
        depth = (h * torch.tanh(dmap)).sum((2, 3)) * (DEPTH_RANGE_MM / 2)          # eq. 1
        alpha = self.root_depth(torch.cat([s16.mean((2, 3)), box], dim=1))
        z_root = RHO_MM * torch.sigmoid(-BETA * alpha)     # eq. 2: rho / (1 + exp(beta alpha)), overflow-safe
        peaks = h.flatten(2).amax(-1)
        confidence = torch.sigmoid(self.confidence(torch.cat([x.mean((2, 3)), peaks], dim=1).detach()))
        return uv, depth, z_root, confidence
