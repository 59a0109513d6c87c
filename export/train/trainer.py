"""Train a ResNet-U from a manifest (export/MANIFEST.md) with the paper's losses (eq. 5, 6).

    python -m export.train --manifest data/train.jsonl --out resnet_u.pt --steps 200000
    python -m export.train --manifest m.jsonl --out small.pt --backbone mobilenetv2 --pretrained --input-size 128

L = L_z + L_p, elastic net (L1 + L2) on z_a (metres) and on the pose (u, v in crop sides, d in
units of the 2 m range); plus an L1 loss teaching the confidence head exp(-e_i / mean e), e_i a
joint's error (the paper trains confidence on the mean error in a second stage; here it is
trained alongside, on detached features). Adam, lr 1e-3, decayed by 0.2 at 75 % and 85 % of the
steps (the paper's 150k/170k of 200k). Ctrl-C saves the checkpoint and exits (code 130).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

from export.model.backbones import load_imagenet_weights
from export.model.checkpoint import load_checkpoint, save_checkpoint
from export.train.dataset import Augment, NO_AUGMENT, PoseDataset, camera_of, read_manifest
from export.model.resnet_u import DEPTH_RANGE_MM, ResNetU, ResNetUConfig
from posecam.errors import PosecamError

err = Console(stderr=True, highlight=False)


@dataclass
class TrainOptions:
    manifest: Path
    out: Path
    backbone: str = "resnet50"
    input_size: int = 256
    head_channels: int = 256
    steps: int = 1000
    batch: int = 24
    lr: float = 1e-3
    init: Path | None = None          # start from this checkpoint (its architecture wins)
    pretrained: bool = False          # ImageNet weights for the backbone (mobilenetv2 only)
    augment: bool = True
    save_every: int = 500
    threads: int | None = None
    seed: int = 0


@dataclass
class TrainResult:
    losses: list[float] = field(default_factory=list)
    steps: int = 0
    interrupted: bool = False


def elastic_net(diff: torch.Tensor) -> torch.Tensor:
    """Mean over samples of ||diff||_1 + ||diff||_2^2 (eq. 5, 6)."""
    d = diff.flatten(1)
    return (d.abs().sum(1) + (d ** 2).sum(1)).mean()


def losses(model: ResNetU, batch: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    uv, depth, z_root, confidence = model(batch["image"], batch["box"])
    size = model.config.input_size
    pred = torch.cat([uv / size, (depth / DEPTH_RANGE_MM)[..., None]], dim=-1)
    true = torch.cat([batch["uv"] / size, (batch["depth"] / DEPTH_RANGE_MM)[..., None]], dim=-1)
    error = (pred - true).detach().norm(dim=-1)
    target = torch.exp(-error / error.mean().clamp_min(1e-6))
    parts = {"pose": elastic_net(pred - true),                                    # eq. 6
             "z": elastic_net((z_root - batch["z_root"]) / 1000.0),               # eq. 5, metres
             "conf": (confidence - target).abs().mean()}
    parts["total"] = parts["pose"] + parts["z"] + parts["conf"]
    return parts


def build_model(opts: TrainOptions, train_focal: float, train_width: float) -> ResNetU:
    if opts.init:
        model = load_checkpoint(opts.init)
        model.config.train_focal, model.config.train_image_width = train_focal, train_width
        return model
    model = ResNetU(ResNetUConfig(backbone=opts.backbone, input_size=opts.input_size,
                                  head_channels=opts.head_channels, train_focal=train_focal,
                                  train_image_width=train_width))
    if opts.pretrained:
        load_imagenet_weights(model.backbone, opts.backbone)
    return model


def train(opts: TrainOptions, show_progress: bool = True) -> TrainResult:
    """Train for opts.steps steps, saving to opts.out every opts.save_every steps and at the end."""
    if opts.threads:
        torch.set_num_threads(opts.threads)
    torch.manual_seed(opts.seed)
    samples = read_manifest(opts.manifest)
    focal, width = camera_of(samples)
    model = build_model(opts, focal, width).train().to(memory_format=torch.channels_last)
    data = PoseDataset(samples, model.config.input_size, focal, width,
                       Augment() if opts.augment else NO_AUGMENT, opts.seed)
    optimiser = torch.optim.Adam(model.parameters(), lr=opts.lr)
    milestones = [int(opts.steps * 0.75), int(opts.steps * 0.85)]
    schedule = torch.optim.lr_scheduler.MultiStepLR(optimiser, milestones, gamma=0.2)
    rng = np.random.default_rng(opts.seed)
    result = TrainResult()
    progress = Progress(TextColumn("training"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[info]}"),
                        TimeRemainingColumn(), console=err, disable=not show_progress)
    task = progress.add_task("train", total=opts.steps, info="")

    def save() -> None:
        loss = result.losses[-1] if result.losses else float("nan")
        save_checkpoint(model, opts.out, {"step": result.steps, "loss": loss, "manifest": str(opts.manifest)})

    try:
        with progress:
            for step in range(opts.steps):
                items = [data[int(i)] for i in rng.integers(len(data), size=opts.batch)]
                batch = {k: torch.stack([it[k] for it in items]) for k in items[0]}
                batch["image"] = batch["image"].contiguous(memory_format=torch.channels_last)
                parts = losses(model, batch)
                optimiser.zero_grad()
                parts["total"].backward()
                optimiser.step()
                schedule.step()
                result.losses.append(parts["total"].item())
                result.steps = step + 1
                progress.update(task, advance=1, info=" ".join(f"{k} {v.item():.3f}" for k, v in parts.items()))
                if opts.save_every and result.steps % opts.save_every == 0:
                    save()
    except KeyboardInterrupt:
        result.interrupted = True
    model.eval()
    save()
    return result


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="python -m export.train", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    d = TrainOptions(Path(), Path())
    ap.add_argument("--manifest", type=Path, required=True, help="JSON-lines manifest (export/MANIFEST.md)")
    ap.add_argument("--out", type=Path, required=True, help="checkpoint to write")
    ap.add_argument("--backbone", default=d.backbone, choices=("resnet50", "resnet34", "resnet18", "mobilenetv2"))
    ap.add_argument("--input-size", type=int, default=d.input_size)
    ap.add_argument("--head-channels", type=int, default=d.head_channels)
    ap.add_argument("--steps", type=int, default=d.steps)
    ap.add_argument("--batch", type=int, default=d.batch)
    ap.add_argument("--lr", type=float, default=d.lr)
    ap.add_argument("--init", type=Path, help="start from this checkpoint")
    ap.add_argument("--pretrained", action="store_true", help="ImageNet backbone weights (mobilenetv2 only)")
    ap.add_argument("--no-augment", dest="augment", action="store_false")
    ap.add_argument("--save-every", type=int, default=d.save_every)
    ap.add_argument("--threads", type=int)
    ap.add_argument("--seed", type=int, default=d.seed)
    opts = TrainOptions(**vars(ap.parse_args(argv)))
    try:
        result = train(opts)
    except PosecamError as exc:
        err.print(f"export.train: error: {exc}")
        sys.exit(exc.exit_code)
    losses_ = result.losses
    summary = f"loss {losses_[0]:.3f} -> {losses_[-1]:.3f}" if losses_ else "no step done"
    if result.interrupted:
        err.print(f"interrupted after {result.steps} steps ({summary}); saved {opts.out}")
        sys.exit(130)
    err.print(f"{result.steps} steps ({summary}); saved {opts.out}")


if __name__ == "__main__":
    main()
