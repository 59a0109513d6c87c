"""posecam's torch side (the optional `export` extra): ResNet-U, checkpoints, training, ONNX export."""

from export.model.checkpoint import load_checkpoint, save_checkpoint
from export.model.resnet_u import ResNetU, ResNetUConfig

__all__ = ["ResNetU", "ResNetUConfig", "load_checkpoint", "save_checkpoint"]
