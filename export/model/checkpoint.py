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

from export.model.resnet_u import (MAX_HEAD_CHANNELS, MAX_INPUT_SIZE, MAX_JOINTS, MAX_U_BLOCKS, ResNetU,
                                    ResNetUConfig)
from posecam.errors import InputError, ModelError
from posecam.io.atomic import atomic_path
from posecam.io.validate import MAX_PIXEL, Field

FORMAT = "posecam.resnet_u"
VERSION = 1
MAX_ENTRIES = 100000      # files in a checkpoint archive (one per tensor, and a few more)


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
    _check_archive(path)
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
    _check_config(payload["config"], Field(str(path), ModelError))
    return payload


def _check_archive(path: Path) -> None:
    """Refuse, before torch opens it, a zip archive that would inflate: torch.save stores its
    tensors uncompressed, so a real checkpoint's entries add up to at most its own size."""
    if not zipfile.is_zipfile(path):
        return                                  # the legacy format: torch reads it as it is
    try:
        with zipfile.ZipFile(path) as archive:
            entries = archive.infolist()
    except (zipfile.BadZipFile, OSError, ValueError):
        raise ModelError(f"{path} is not a posecam ResNet-U checkpoint (a damaged zip archive)") from None
    unpacked = sum(e.file_size for e in entries)
    if len(entries) > MAX_ENTRIES or unpacked > path.stat().st_size + (1 << 20):
        raise ModelError(f"{path}: checkpoint archive would unpack to {unpacked / 1e6:.0f} MB in {len(entries)} "
                         f"entries from {path.stat().st_size / 1e6:.1f} MB; torch.save writes it uncompressed "
                         "(a zip bomb?)")


def _check_config(config: dict, check: Field) -> None:
    """The config's types and ranges, before a layer is built from it (ResNetUConfig checks
    the values once they are known to be numbers)."""
    if "backbone" in config:
        check.text(config["backbone"], "config.backbone", limit=64)
    if "joints" in config:
        for name in check.items(config["joints"], "config.joints", MAX_JOINTS):
            check.text(name, "config.joints", limit=64)
    for key, hi in (("input_size", MAX_INPUT_SIZE), ("head_channels", MAX_HEAD_CHANNELS), ("u_blocks", MAX_U_BLOCKS)):
        if key in config:
            check.number(config[key], f"config.{key}", 1, hi, whole=True)
    for key in ("train_focal", "train_image_width"):
        if key in config:
            check.number(config[key], f"config.{key}", 0, MAX_PIXEL, open_lo=True)


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
