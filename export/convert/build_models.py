"""Build posecam's bundled models from MediaPipe's BlazePose TFLite files (Apache-2.0).

    python -m export.convert.build_models                  # detector, lite, full -> posecam/models/
    python -m export.convert.build_models heavy --out DIR  # heavy on request (28 MB source, not bundled)

Each file gets the model contract's metadata (posecam/contract.py) and keeps only the outputs
the runtime uses: the landmark models' segmentation mask and heatmaps are pruned away, which
also removes the decoder branches that only fed them. MODEL_CARD.md is rewritten with the
source package, the sha256 of source and result, and this command.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import onnx

from export.assets import PACKAGES, FILES, asset_path, sha256
from export.convert.tflite_onnx import convert
from posecam.inference.contract import InputSpec, ModelContract
from posecam.skeleton import BLAZEPOSE_LANDMARKS

MODELS_DIR = Path(__file__).resolve().parents[2] / "posecam" / "models"
BUNDLED = ("detector", "lite", "full")

DETECTOR = ModelContract(
    kind="detector", name="blazepose-detector",
    input=InputSpec("input_1", "NHWC", (224, 224), (0.5, 0.5, 0.5), (0.5, 0.5, 0.5)),
    outputs={"boxes": "Identity", "scores": "Identity_1"},
    anchors={"strides": [8, 16, 32], "anchors_per_cell": [2, 2, 6], "scale": 224},
)


def landmark_contract(variant: str) -> ModelContract:
    return ModelContract(
        kind="landmarks", name=f"blazepose-{variant}",
        input=InputSpec("input_1", "NHWC", (256, 256)),
        outputs={"landmarks": "Identity", "presence": "Identity_1", "world": "Identity_4"},
        joints=BLAZEPOSE_LANDMARKS,
    )


def source_file(variant: str) -> str:
    return "pose_detection.tflite" if variant == "detector" else f"pose_landmark_{variant}.tflite"


def build(variant: str, out_dir: Path = MODELS_DIR) -> Path:
    """Convert one variant ("detector", "lite", "full", "heavy") and write blazepose_<variant>.onnx."""
    contract = DETECTOR if variant == "detector" else landmark_contract(variant)
    model = convert(asset_path(source_file(variant)), outputs=list(contract.outputs.values()))
    for key, value in contract.to_metadata().items():
        model.metadata_props.add(key=key, value=value)
    out_dir.mkdir(parents=True, exist_ok=True)
    out = out_dir / f"blazepose_{variant}.onnx"
    tmp = out.with_suffix(".onnx.part")
    onnx.save(model, tmp)
    tmp.replace(out)
    return out


def write_card(variants: tuple[str, ...], out_dir: Path = MODELS_DIR) -> Path:
    rows = []
    for v in variants:
        package = PACKAGES[FILES[source_file(v)][0]]
        rows.append(f"| `blazepose_{v}.onnx` | `{source_file(v)}` from {package.registry} `{package.spec}` "
                    f"| `{sha256(asset_path(source_file(v)))}` | `{sha256(out_dir / f'blazepose_{v}.onnx')}` |")
    text = CARD.format(rows="\n".join(rows))
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
(`posecam/contract.py`).

| file | source | sha256 of source | sha256 of result |
|---|---|---|---|
{rows}

Rebuild (fetches the packages into `.cache/assets`, needs the `export` extra and ai-edge-litert):

```bash
python -m export.convert.build_models            # detector, lite, full
python -m export.convert.build_models heavy      # heavy, on request: --model heavy then finds it here
```
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("variants", nargs="*", help="detector, lite, full, heavy (default: the bundled ones)")
    ap.add_argument("--out", type=Path, default=MODELS_DIR)
    a = ap.parse_args()
    unknown = set(a.variants) - {*BUNDLED, "heavy"}
    if unknown:
        ap.error(f"unknown variants: {', '.join(sorted(unknown))}")
    for v in a.variants or BUNDLED:
        print(f"{build(v, a.out)}")
    if a.out == MODELS_DIR:
        built = tuple(v for v in (*BUNDLED, "heavy") if (MODELS_DIR / f"blazepose_{v}.onnx").exists())
        print(write_card(built))


if __name__ == "__main__":
    main()
