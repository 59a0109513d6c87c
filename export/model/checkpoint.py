"""ResNet-U checkpoints: one torch file holding the weights and the config that rebuilds them.

Format (a dict saved with ``torch.save``, loadable with ``torch.load(weights_only=True)``):

    {"format": "posecam.resnet_u", "version": 1,
     "config": {"backbone", "joints", "input_size", "head_channels", "u_blocks",
                "train_focal", "train_image_width"},     # ResNetUConfig.to_dict()
     "state_dict": {name: tensor},
     "train": {"step": int, "loss": float, ...}}        # informative, may be empty
"""

from __future__ import annotations

import os
import pickle
import zipfile
from pathlib import Path

import torch

from export.model.resnet_u import ResNetU, ResNetUConfig
from posecam.errors import InputError, ModelError
from posecam.io.atomic import atomic_path

FORMAT = "posecam.resnet_u"
VERSION = 1


def save_checkpoint(model: ResNetU, path: str | os.PathLike, train: dict | None = None) -> None:
    """Write `model` (and optional training facts) to `path` atomically."""
    payload = {"format": FORMAT, "version": VERSION, "config": model.config.to_dict(),
               "state_dict": {k: v.detach().cpu().contiguous() for k, v in model.state_dict().items()},
               "train": dict(train or {})}
    with atomic_path(path) as tmp:
        torch.save(payload, tmp)


def read_checkpoint(path: str | os.PathLike) -> dict:
    """The checked checkpoint dict; ModelError for anything that is not a ResNet-U checkpoint."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"checkpoint {path} does not exist")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except (pickle.UnpicklingError, zipfile.BadZipFile, RuntimeError, EOFError, ValueError, OSError):
        raise ModelError(f"{path} is not a posecam ResNet-U checkpoint "
                         "(torch.load(weights_only=True) cannot read it)") from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise ModelError(f"{path} is not a posecam ResNet-U checkpoint (no format={FORMAT!r} entry)")
    if payload.get("version") != VERSION:
        raise ModelError(f"{path}: checkpoint version {payload.get('version')!r} is not supported (expected {VERSION})")
    if not isinstance(payload.get("config"), dict) or not isinstance(payload.get("state_dict"), dict):
        raise ModelError(f"{path}: checkpoint lacks its config or state_dict")
    return payload


def load_checkpoint(path: str | os.PathLike) -> ResNetU:
    """Rebuild the ResNet-U saved in `path`, in eval mode."""
    payload = read_checkpoint(path)
    try:
        model = ResNetU(ResNetUConfig.from_dict(payload["config"]))
    except (InputError, TypeError) as exc:
        raise ModelError(f"{path}: bad ResNet-U config in checkpoint ({exc})") from None
    try:
        model.load_state_dict(payload["state_dict"])
    except RuntimeError as exc:
        raise ModelError(f"{path}: weights do not match the config ({str(exc).splitlines()[0][:160]})") from None
    return model.eval()
