"""The posecam model contract: what an ONNX file's metadata must say for the runtime to run it.

Every model is recognised from its `metadata_props`, never from its file name. Keys:

- ``posecam.contract``  "1"
- ``posecam.kind``      "detector" | "landmarks" (metric root-relative pose + 2D, BlazePose)
                         | "root_depth" (the paper's ResNet-U: u, v, relative depth, z_a)
                         | "embedder" (a person crop's appearance vector, for the tracker)
- ``posecam.name``      a short model name, e.g. "blazepose-full"
- ``posecam.joints``    JSON list of the joint names the model outputs, in output order
- ``posecam.input``     JSON {"name", "layout": "NHWC"|"NCHW", "size": [h, w],
                         "mean": [3], "std": [3]}: pixel = (rgb / 255 - mean) / std;
                         optional "multiple": k when the graph takes any H, W that are multiples
                         of k ("size" is then the default, its larger side the long side)
- ``posecam.decoder``   detectors only: "blazepose_ssd" (the default when absent) or
                         "movenet_multipose"
- ``posecam.outputs``   JSON {role: output name}; roles per kind:
    detector, blazepose_ssd:     "boxes" [1, A, 12], "scores" [1, A, 1]; plus ``posecam.anchors``
                                 JSON {"strides", "anchors_per_cell", "scale"}
    detector, movenet_multipose: "people" [1, P, 3 * K + 5]: per candidate K x (y, x, score) then
                                 ymin, xmin, ymax, xmax, score, all normalised to the input;
                                 ``posecam.joints`` names the K keypoints
    landmarks:  "landmarks" [N, L*5], "presence" [N, 1], "world" [N, L*3]
    root_depth: "uv" [N, J, 2] crop pixels, "depth" [N, J] mm relative to the root,
                "z_root" [N, 1] mm, "confidence" [N, J] in [0, 1]; a second input
                ``posecam.box_input`` [N, 4] takes the box (cx/W, cy/H, w/W, h/H)
    embedder:   "embedding" [N, D] unit vectors, one per crop of a person's box stretched to
                the input size (no joints)
- root_depth only: ``posecam.train_focal`` focal length (px) of the training camera and
  ``posecam.train_image_width`` its image width (px). z_a is rescaled by
  (f / W) / (f_train / W_train), which is f / f_train for images of the training width.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

from posecam.errors import ModelError

CONTRACT_VERSION = "1"
# The bundled models (light to import, for the CLI's choices): the names --model and --detector
# take and their files in posecam/models/, built by `python -m export.convert.build_models NAME`
# ("heavy" on request, not committed). How each is run comes from its file's metadata.
POSE_MODELS = {"lite": "blazepose_lite.onnx", "full": "blazepose_full.onnx", "heavy": "blazepose_heavy.onnx"}
DETECTORS = {"movenet": "movenet_multipose.onnx", "blazepose": "blazepose_detector.onnx"}
EMBEDDERS = {"mobilenetv2": "appearance_mobilenetv2.onnx"}
ON_REQUEST = ("heavy",)
KINDS = ("detector", "landmarks", "root_depth", "embedder")
DECODERS = {  # detector decoders and the outputs each needs
    "blazepose_ssd": ("boxes", "scores"),
    "movenet_multipose": ("people",),
}
REQUIRED_OUTPUTS = {
    "landmarks": ("landmarks", "presence", "world"),
    "root_depth": ("uv", "depth", "z_root", "confidence"),
    "embedder": ("embedding",),
}


@dataclass(frozen=True)
class InputSpec:
    name: str
    layout: str
    size: tuple[int, int]
    mean: tuple[float, float, float] = (0.0, 0.0, 0.0)
    std: tuple[float, float, float] = (1.0, 1.0, 1.0)
    multiple: int = 0    # > 0: any H, W that are multiples of it (size is the default)


@dataclass(frozen=True)
class ModelContract:
    kind: str
    name: str
    input: InputSpec
    outputs: dict[str, str]
    joints: tuple[str, ...] = ()
    anchors: dict = field(default_factory=dict)
    box_input: str | None = None
    train_focal: float | None = None
    train_image_width: float | None = None
    decoder: str = ""

    def to_metadata(self) -> dict[str, str]:
        """The metadata_props that describe this model."""
        meta = {
            "posecam.contract": CONTRACT_VERSION,
            "posecam.kind": self.kind,
            "posecam.name": self.name,
            "posecam.joints": json.dumps(list(self.joints)),
            "posecam.input": json.dumps(
                {"name": self.input.name, "layout": self.input.layout, "size": list(self.input.size),
                 "mean": list(self.input.mean), "std": list(self.input.std),
                 **({"multiple": self.input.multiple} if self.input.multiple else {})}
            ),
            "posecam.outputs": json.dumps(self.outputs),
        }
        if self.decoder:
            meta["posecam.decoder"] = self.decoder
        if self.anchors:
            meta["posecam.anchors"] = json.dumps(self.anchors)
        if self.box_input:
            meta["posecam.box_input"] = self.box_input
        if self.train_focal is not None:
            meta["posecam.train_focal"] = repr(float(self.train_focal))
            meta["posecam.train_image_width"] = repr(float(self.train_image_width))
        return meta

    @classmethod
    def from_metadata(cls, meta: dict[str, str], source: str) -> "ModelContract":
        """Parse and check metadata; raise ModelError naming what is wrong."""
        if meta.get("posecam.contract") != CONTRACT_VERSION:
            raise ModelError(f"{source} is not a posecam model (no posecam.contract={CONTRACT_VERSION} metadata)")
        kind = meta.get("posecam.kind")
        if kind not in KINDS:
            raise ModelError(f"{source}: unknown model kind {kind!r}; expected one of {', '.join(KINDS)}")
        try:
            inp = json.loads(meta["posecam.input"])
            outputs = json.loads(meta["posecam.outputs"])
            joints = json.loads(meta.get("posecam.joints", "[]"))
            anchors = json.loads(meta.get("posecam.anchors", "{}"))
        except (KeyError, ValueError, RecursionError) as exc:
            raise ModelError(f"{source}: malformed posecam metadata ({exc!r})") from None
        spec, outputs, joints, train_focal, train_width = _checked(source, inp, outputs, joints, meta)
        decoder = meta.get("posecam.decoder", "blazepose_ssd" if kind == "detector" else "")
        if kind == "detector" and decoder not in DECODERS:
            raise ModelError(f"{source}: unknown detector decoder {decoder!r}; expected one of {', '.join(DECODERS)}")
        missing = [r for r in (DECODERS[decoder] if kind == "detector" else REQUIRED_OUTPUTS[kind]) if r not in outputs]
        if missing:
            raise ModelError(f"{source}: {kind} model lacks outputs for {', '.join(missing)}")
        if spec.layout not in ("NHWC", "NCHW"):
            raise ModelError(f"{source}: input layout must be NHWC or NCHW, got {spec.layout!r}")
        if (kind in ("landmarks", "root_depth") or decoder == "movenet_multipose") and not joints:
            raise ModelError(f"{source}: {kind} model does not list its joints")
        if kind == "root_depth" and (train_focal is None or train_width is None or "posecam.box_input" not in meta):
            raise ModelError(f"{source}: root_depth model needs posecam.train_focal, "
                             "posecam.train_image_width and posecam.box_input")
        return cls(kind, meta.get("posecam.name", source), spec, outputs, joints, anchors,
                   meta.get("posecam.box_input"), train_focal, train_width, decoder)


MAX_INPUT_SIDE = 2048      # pixels: a model input's height or width (a 40000 px one is refused)


def _checked(source: str, inp: object, outputs: object, joints: object, meta: dict[str, str]):
    """The metadata's values, each checked (posecam.io.validate) before anything is allocated
    from them: input size whole numbers in 1..MAX_INPUT_SIDE, mean and std 3 finite numbers
    (std not 0), multiple 0..256, outputs and joints strings, training camera positive."""
    from posecam.io.validate import MAX_JOINTS, MAX_PIXEL, Field

    check = Field(source, ModelError)
    check.table(inp, "posecam.input")
    for key in ("name", "layout", "size"):
        if key not in inp:
            raise check.fail(f"posecam.input.{key}", "is missing")
    size = check.numbers(inp["size"], "posecam.input.size", ((2,),), 1, MAX_INPUT_SIDE)
    if not all(float(v).is_integer() for v in size):
        raise check.fail("posecam.input.size", "must be 2 whole numbers", size.tolist())
    mean = check.numbers(inp.get("mean", [0, 0, 0]), "posecam.input.mean", ((3,),), -1e3, 1e3)
    std = check.numbers(inp.get("std", [1, 1, 1]), "posecam.input.std", ((3,),), -1e3, 1e3)
    if not std.all():
        raise check.fail("posecam.input.std", "must not be 0", std.tolist())
    multiple = check.number(inp.get("multiple", 0), "posecam.input.multiple", 0, 256, whole=True)
    spec = InputSpec(check.text(inp["name"], "posecam.input.name"), check.text(inp["layout"], "posecam.input.layout"),
                     (int(size[0]), int(size[1])), tuple(map(float, mean)), tuple(map(float, std)), multiple)
    check.table(outputs, "posecam.outputs")
    outputs = {check.text(k, "posecam.outputs"): check.text(v, f"posecam.outputs.{k}") for k, v in outputs.items()}
    names = check.items(joints, "posecam.joints", MAX_JOINTS)
    joints = tuple(check.text(j, "posecam.joints", limit=64) for j in names)
    train = []
    for key in ("posecam.train_focal", "posecam.train_image_width"):
        if key not in meta:
            train.append(None)
            continue
        try:
            value = float(meta[key])
        except ValueError:
            raise check.fail(key, "must be a number", meta[key]) from None
        train.append(float(check.number(value, key, 0, MAX_PIXEL, open_lo=True)))
    return spec, outputs, joints, train[0], train[1]
