"""A small TF.js graph model -> ONNX converter (MoveNet MultiPose).

A TF.js graph model is a `model.json` holding a TensorFlow GraphDef as JSON (`modelTopology`)
and a `weightsManifest` describing the binary shards next to it. Every Const node's value is
in the shards, possibly quantised: float16, or uint8/uint16 with an affine scale and min; they
are dequantised to float32 (int32 for int32 originals) as TF.js does it, except that float16
weights are by default kept as float16 initializers read through a Cast (exact, half the file).
The graph is rebuilt with
`onnx.helper`, node by node, in the style of `tflite_onnx.py`: 4-D activations are held in NCHW
inside the ONNX graph (convolutions, pooling, resizing and the elementwise ops between them),
while the graph inputs and outputs keep the TF.js layout. Everything else (shape arithmetic,
StridedSlice, GatherNd, TopK of MoveNet's decoder) is translated in TF layout, transposing a
4-D NCHW value back only where such an op reads it. Nodes whose inputs are all constant are
folded with numpy where a rule exists (Cast, Pack, Reshape and the elementwise ops).

Input dimensions that the TF.js signature leaves open (-1) stay dynamic in ONNX: MoveNet
MultiPose runs at any height and width that are multiples of 32. Non-float inputs may be
turned into float32 ones (`float_inputs=True`) when their only consumers are Casts to float,
e.g. MoveNet's int32 RGB input, so that callers feed float32 0..255 pixels.

Saved with IR version 9 / opset 17 (onnxruntime 1.31 refuses IR 14).
"""

from __future__ import annotations

import base64
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from export.convert.tflite_onnx import _NCHW_TO_NHWC, _NHWC_TO_NCHW, ConversionError, finish_model

_TF_DTYPES = {"DT_FLOAT": np.float32, "DT_INT32": np.int32, "DT_INT64": np.int64, "DT_BOOL": np.bool_}
_JS_DTYPES = {"float32": np.float32, "int32": np.int32, "bool": np.bool_}
_QUANT_DTYPES = {"uint8": np.uint8, "uint16": np.uint16, "float16": np.float16}
_ONNX_TYPES = {np.dtype(np.float32): TensorProto.FLOAT, np.dtype(np.int32): TensorProto.INT32,
               np.dtype(np.int64): TensorProto.INT64, np.dtype(np.bool_): TensorProto.BOOL}
_INT64_MAX = np.iinfo(np.int64).max
_INT64_MIN = np.iinfo(np.int64).min

_UNARY = {"Sigmoid": "Sigmoid", "Relu": "Relu", "Exp": "Exp", "Abs": "Abs", "Reciprocal": "Reciprocal",
          "Identity": "Identity", "Neg": "Neg", "Sqrt": "Sqrt", "Floor": "Floor", "Tanh": "Tanh"}
_BINARY = {"Add": "Add", "AddV2": "Add", "Sub": "Sub", "Mul": "Mul", "RealDiv": "Div", "Maximum": "Max",
           "Minimum": "Min", "Less": "Less", "Greater": "Greater", "LessEqual": "LessOrEqual",
           "GreaterEqual": "GreaterOrEqual", "Equal": "Equal", "LogicalAnd": "And", "LogicalOr": "Or"}
_COMPARISONS = {"Less", "Greater", "LessEqual", "GreaterEqual", "Equal", "LogicalAnd", "LogicalOr"}
# numpy rules for nodes whose inputs are all known at conversion time
_FOLD = {
    "Add": np.add, "AddV2": np.add, "Sub": np.subtract, "Mul": np.multiply, "Maximum": np.maximum,
    "Minimum": np.minimum, "FloorDiv": np.floor_divide, "Identity": lambda x: x,
}


# --- reading the model --------------------------------------------------------------------------

def _decode_group(group: dict, directory: Path, keep_float16: bool) -> dict[str, np.ndarray]:
    data = b"".join((directory / p).read_bytes() for p in group["paths"])
    out, offset = {}, 0
    for spec in group["weights"]:
        shape = [int(s) for s in spec["shape"]]
        count = int(np.prod(shape, dtype=np.int64))
        if spec["dtype"] not in _JS_DTYPES:
            raise ConversionError(f"weight {spec['name']} has dtype {spec['dtype']}, which is not supported")
        dtype = np.dtype(_JS_DTYPES[spec["dtype"]])
        quant = spec.get("quantization")
        stored = np.dtype(_QUANT_DTYPES[quant["dtype"]]) if quant else dtype
        raw = np.frombuffer(data, stored, count, offset).reshape(shape)
        offset += count * stored.itemsize
        if quant and quant["dtype"] == "float16":
            values = raw.copy() if keep_float16 and dtype == np.float32 else raw.astype(dtype)
        elif quant:  # affine uint8 / uint16: q * scale + min in double precision, as tfjs does;
            values = raw.astype(np.float64) * quant["scale"] + quant["min"]  # int32: JS Math.round
            values = np.floor(values + 0.5).astype(dtype) if dtype.kind == "i" else values.astype(dtype)
        else:
            values = raw.copy()
        out[spec["name"]] = values
    if offset != len(data):
        raise ConversionError(f"weight shards {group['paths']} hold {len(data)} bytes, the manifest {offset}")
    return out


def load_tfjs(model_json: str | os.PathLike, keep_float16: bool = False) -> tuple[dict, dict[str, np.ndarray]]:
    """The parsed model.json and its weights by Const node name, dequantised.

    `keep_float16` leaves float16-quantised float32 weights in float16 (exactly representable).
    """
    path = Path(model_json)
    spec = json.loads(path.read_text())
    if spec.get("format") not in (None, "graph-model"):
        raise ConversionError(f"{path}: format {spec.get('format')!r} is not a TF.js graph model")
    weights: dict[str, np.ndarray] = {}
    for group in spec["weightsManifest"]:
        weights.update(_decode_group(group, path.parent, keep_float16))
    return spec, weights


# --- helpers ------------------------------------------------------------------------------------

def _attr(node: dict, key: str, default=None):
    """A node attribute as a Python value (ints, floats, strings, bools, lists, dtypes)."""
    a = node.get("attr", {}).get(key)
    if a is None:
        return default
    if "list" in a:
        lst = a["list"]
        if "i" in lst:
            return [int(v) for v in lst["i"]]
        if "f" in lst:
            return [float(v) for v in lst["f"]]
        if "s" in lst:
            return [base64.b64decode(v).decode() for v in lst["s"]]
        return []
    if "i" in a:
        return int(a["i"])
    if "f" in a:
        return float(a["f"])
    if "b" in a:
        return bool(a["b"])
    if "s" in a:
        return base64.b64decode(a["s"]).decode()
    if "type" in a:
        return np.dtype(_TF_DTYPES[a["type"]])
    if "shape" in a:
        return [int(d.get("size", -1)) for d in a["shape"].get("dim", [])]
    return a


def _ref(name: str) -> str:
    """A tensor reference as "node:index"."""
    return name if ":" in name else f"{name}:0"


def _broadcast(*shapes: tuple) -> tuple:
    rank = max(len(s) for s in shapes)
    out = []
    for dims in zip(*[(1,) * (rank - len(s)) + tuple(s) for s in shapes]):
        known = {d for d in dims if d is not None and d != 1}
        out.append(known.pop() if len(known) == 1 else None if (None in dims or known) else 1)
    return tuple(out)


def _conv_out(size, kernel: int, stride: int, dilation: int, padding: str):
    if size is None:
        return None
    if padding == "SAME":
        return -(-size // stride)
    return -(-(size - (kernel - 1) * dilation) // stride)


def _tf_dtype(array: np.ndarray) -> np.dtype:
    """The dtype TF sees: weights kept in float16 are float32 there."""
    return np.dtype(np.float32) if array.dtype == np.float16 else array.dtype


def _weights(array: np.ndarray) -> np.ndarray:
    """Float weights as stored: float16 where they were kept so, float32 otherwise."""
    return array if array.dtype == np.float16 else array.astype(np.float32)


@dataclass
class _Value:
    name: str            # the ONNX value
    nchw: bool           # a 4-D tensor held in NCHW inside the ONNX graph
    shape: tuple         # the TF shape (TF layout); None for dimensions unknown here
    dtype: np.dtype


class _Builder:
    """Walks the GraphDef nodes in order and emits ONNX nodes.

    Not a subclass of the TFLite builder: its op_<name> methods are dispatched by TFLite operator
    names (ADD, PAD, ...) that collide with TF op names of other meaning.
    """

    def __init__(self, weights: dict[str, np.ndarray]):
        self.known: dict[str, np.ndarray] = {_ref(k): v for k, v in weights.items()}
        self.values: dict[str, _Value] = {}
        self.nodes: list[onnx.NodeProto] = []
        self.initializers: list[onnx.TensorProto] = []
        self._count = 0
        self._materialised: dict[str, str] = {}
        self._transposed: dict[tuple[str, bool], str] = {}

    def fresh(self, hint: str) -> str:
        self._count += 1
        return f"{hint}_{self._count}"

    def const(self, array: np.ndarray, hint: str) -> str:
        """An initializer; float16 ones (weights stored so) are read through a Cast to float32."""
        name = self.fresh(hint)  # np.array, not np.ascontiguousarray: TF scalars must stay 0-d
        self.initializers.append(numpy_helper.from_array(np.array(array, order="C"), name))
        if array.dtype == np.float16:
            return self.node("Cast", [name], to=TensorProto.FLOAT)
        return name

    def node(self, op: str, inputs: list[str], output: str | None = None, **attrs) -> str:
        output = output or self.fresh(op.lower())
        self.nodes.append(helper.make_node(op, inputs, [output], name=self.fresh("n"), **attrs))
        return output

    # --- values ---------------------------------------------------------------------------

    def info(self, ref: str) -> _Value:
        if ref in self.values:
            return self.values[ref]
        if ref in self.known:
            c = self.known[ref]
            if ref not in self._materialised:
                self._materialised[ref] = self.const(c, "k")
            return _Value(self._materialised[ref], False, c.shape, _tf_dtype(c))
        raise ConversionError(f"tensor {ref} is used before it is produced")

    def rank(self, ref: str) -> int:
        return len(self.info(ref).shape)

    def tf(self, ref: str) -> str:
        """The value in TF layout."""
        v = self.info(ref)
        if not v.nchw:
            return v.name
        key = (ref, False)
        if key not in self._transposed:
            self._transposed[key] = self.node("Transpose", [v.name], perm=_NCHW_TO_NHWC)
        return self._transposed[key]

    def nchw(self, ref: str) -> str:
        """A 4-D NHWC value in NCHW."""
        v = self.info(ref)
        if v.nchw:
            return v.name
        if len(v.shape) != 4:
            raise ConversionError(f"{ref} is not 4-D")
        if ref in self.known:
            return self.const(np.ascontiguousarray(self.known[ref].transpose(_NHWC_TO_NCHW)), "k")
        key = (ref, True)
        if key not in self._transposed:
            self._transposed[key] = self.node("Transpose", [v.name], perm=_NHWC_TO_NCHW)
        return self._transposed[key]

    def ints(self, ref: str, hint: str = "i") -> str:
        """An integer tensor as int64 (ONNX shape-like inputs)."""
        if ref in self.known:
            return self.const(self.known[ref].astype(np.int64), hint)
        return self.node("Cast", [self.tf(ref)], to=TensorProto.INT64)

    def value(self, ref: str) -> np.ndarray:
        if ref not in self.known:
            raise ConversionError(f"{ref} must be a constant here")
        return self.known[ref]

    def emit(self, node: dict) -> None:
        op = node["op"]
        ins = [_ref(i) for i in node.get("input", []) if not i.startswith("^")]
        if op == "Const":
            if _ref(node["name"]) not in self.known:
                raise ConversionError(f"Const {node['name']} has no weights in the manifest")
            return
        if all(i in self.known for i in ins) and ins and self.fold(node, op, ins):
            return
        method = getattr(self, "op_" + op.lower(), None)
        if method is None and op in _UNARY:
            method = self._unary
        elif method is None and op in _BINARY:
            method = self._binary
        if method is None:
            raise ConversionError(f"TF op {op} ({node['name']}) is not supported")
        outs = method(node, ins)
        for k, v in enumerate(outs if isinstance(outs, list) else [outs]):
            self.values[f"{node['name']}:{k}"] = v

    def fold(self, node: dict, op: str, ins: list[str]) -> bool:
        args = [self.known[i].astype(_tf_dtype(self.known[i])) for i in ins]
        if op in _FOLD:
            result = _FOLD[op](*args)
        elif op == "Cast":
            result = args[0].astype(_attr(node, "DstT"))
        elif op == "Pack":
            result = np.stack(args, axis=_attr(node, "axis", 0))
        elif op == "Reshape":
            result = args[0].reshape(args[1].astype(np.int64))
        else:
            return False
        self.known[f"{node['name']}:0"] = np.asarray(result)
        return True

    # --- layout-aware operators -----------------------------------------------------------

    def _unary(self, node, ins):
        v = self.info(ins[0])
        return _Value(self.node(_UNARY[node["op"]], [v.name]), v.nchw, v.shape, v.dtype)

    def _elementwise(self, onnx_op: str, ins: list[str], **attrs) -> _Value:
        shapes = [self.info(i).shape for i in ins]
        shape = _broadcast(*shapes)
        dtype = self.info(ins[0]).dtype
        four_d = len(shape) == 4 and any(self.info(i).nchw for i in ins) and all(
            i in self.known or self.rank(i) == 4 for i in ins)
        operands = []
        for i in ins:
            if not four_d:
                operands.append(self.tf(i))
            elif i in self.known:  # NHWC broadcast constant -> NCHW
                c = self.known[i]
                c = c.reshape((1,) * (4 - c.ndim) + c.shape).transpose(_NHWC_TO_NCHW)
                operands.append(self.const(np.ascontiguousarray(c), "c"))
            else:
                operands.append(self.nchw(i))
        return _Value(self.node(onnx_op, operands, **attrs), four_d, shape, dtype)

    def _binary(self, node, ins):
        v = self._elementwise(_BINARY[node["op"]], ins)
        if node["op"] in _COMPARISONS:
            v.dtype = np.dtype(np.bool_)
        return v

    def op_squareddifference(self, node, ins):
        d = self._elementwise("Sub", ins)
        return _Value(self.node("Mul", [d.name, d.name]), d.nchw, d.shape, d.dtype)

    def op_floordiv(self, node, ins):
        if self.info(ins[0]).dtype.kind == "f":
            v = self._elementwise("Div", ins)
            return _Value(self.node("Floor", [v.name]), v.nchw, v.shape, v.dtype)
        # integers: through float32 (exact below 2**24, which the indices and sizes here are)
        a, b = (self.node("Cast", [self.tf(i)], to=TensorProto.FLOAT) for i in ins)
        q = self.node("Floor", [self.node("Div", [a, b])])
        dtype = self.info(ins[0]).dtype
        shape = _broadcast(self.info(ins[0]).shape, self.info(ins[1]).shape)
        return _Value(self.node("Cast", [q], to=_ONNX_TYPES[dtype]), False, shape, dtype)

    def op_addn(self, node, ins):
        return self._elementwise("Sum", ins)

    def op_cast(self, node, ins):
        v = self.info(ins[0])
        dtype = _attr(node, "DstT")
        if v.dtype == dtype:
            return _Value(v.name, v.nchw, v.shape, dtype)
        return _Value(self.node("Cast", [v.name], to=_ONNX_TYPES[dtype]), v.nchw, v.shape, dtype)

    def op_relu6(self, node, ins):
        v = self.info(ins[0])
        return _Value(self._activation(v.name, "Relu6", 0.0), v.nchw, v.shape, v.dtype)

    def op_leakyrelu(self, node, ins):
        v = self.info(ins[0])
        return _Value(self.node("LeakyRelu", [v.name], alpha=_attr(node, "alpha", 0.2)), v.nchw, v.shape, v.dtype)

    def _activation(self, name: str, fused: str, alpha: float) -> str:
        if fused == "Relu":
            return self.node("Relu", [name])
        if fused == "Relu6":
            return self.node("Clip", [name, self.const(np.float32(0), "zero"), self.const(np.float32(6), "six")])
        if fused == "LeakyRelu":
            return self.node("LeakyRelu", [name], alpha=alpha)
        if fused == "Sigmoid":
            return self.node("Sigmoid", [name])
        raise ConversionError(f"fused activation {fused} is not supported")

    def _conv(self, node, ins, depthwise: bool, fused: bool):
        if _attr(node, "data_format", "NHWC") != "NHWC":
            raise ConversionError(f"{node['name']}: only NHWC convolutions are supported")
        padding = _attr(node, "padding")
        if padding not in ("SAME", "VALID"):
            raise ConversionError(f"{node['name']}: padding {padding} is not supported")
        w = _weights(self.value(ins[1]))
        kh, kw, cin, m = w.shape
        if depthwise:  # [kh, kw, C, m] -> [C*m, 1, kh, kw]
            w = w.reshape(kh, kw, cin * m).transpose(2, 0, 1)[:, None]
        else:          # [kh, kw, I, O] -> [O, I, kh, kw]
            w = w.transpose(3, 2, 0, 1)
        strides = _attr(node, "strides")[1:3]
        dilations = (_attr(node, "dilations") or [1, 1, 1, 1])[1:3]
        inputs = [self.nchw(ins[0]), self.const(np.ascontiguousarray(w), "w")]
        ops = _attr(node, "fused_ops", []) if fused else []
        if ops and ops[0] == "BiasAdd":
            inputs.append(self.const(_weights(self.value(ins[2])), "b"))
            ops = ops[1:]
        elif ops:
            raise ConversionError(f"{node['name']}: fused ops {ops} are not supported")
        y = self.node("Conv", inputs, kernel_shape=[kh, kw], strides=strides, dilations=dilations,
                      auto_pad="SAME_UPPER" if padding == "SAME" else "VALID", group=cin if depthwise else 1)
        for act in ops:
            y = self._activation(y, act, _attr(node, "leakyrelu_alpha", 0.2))
        n, h, wd, _ = self.info(ins[0]).shape
        shape = (n, _conv_out(h, kh, strides[0], dilations[0], padding),
                 _conv_out(wd, kw, strides[1], dilations[1], padding), w.shape[0])
        return _Value(y, True, shape, np.dtype(np.float32))

    def op__fusedconv2d(self, node, ins):
        return self._conv(node, ins, depthwise=False, fused=True)

    def op_fuseddepthwiseconv2dnative(self, node, ins):
        return self._conv(node, ins, depthwise=True, fused=True)

    def op_conv2d(self, node, ins):
        return self._conv(node, ins, depthwise=False, fused=False)

    def op_depthwiseconv2dnative(self, node, ins):
        return self._conv(node, ins, depthwise=True, fused=False)

    def op_maxpool(self, node, ins):
        if _attr(node, "data_format", "NHWC") != "NHWC":
            raise ConversionError(f"{node['name']}: only NHWC pooling is supported")
        kernel, strides, padding = _attr(node, "ksize")[1:3], _attr(node, "strides")[1:3], _attr(node, "padding")
        y = self.node("MaxPool", [self.nchw(ins[0])], kernel_shape=kernel, strides=strides,
                      auto_pad="SAME_UPPER" if padding == "SAME" else "VALID")
        n, h, w, c = self.info(ins[0]).shape
        shape = (n, _conv_out(h, kernel[0], strides[0], 1, padding), _conv_out(w, kernel[1], strides[1], 1, padding), c)
        return _Value(y, True, shape, self.info(ins[0]).dtype)

    def op_resizebilinear(self, node, ins):
        mode = ("align_corners" if _attr(node, "align_corners") else
                "half_pixel" if _attr(node, "half_pixel_centers") else "asymmetric")
        x = self.nchw(ins[0])
        nc = self.node("Slice", [self.node("Shape", [x]), self.const(np.array([0], np.int64), "s"),
                                 self.const(np.array([2], np.int64), "e")])
        sizes = self.node("Concat", [nc, self.ints(ins[1])], axis=0)
        y = self.node("Resize", [x, "", "", sizes], mode="linear", coordinate_transformation_mode=mode)
        v = self.info(ins[0])
        hw = tuple(int(s) for s in self.known[ins[1]]) if ins[1] in self.known else (None, None)
        return _Value(y, True, (v.shape[0], *hw, v.shape[3]), v.dtype)

    def op_concatv2(self, node, ins):
        values, axis = ins[:-1], int(self.value(ins[-1]))
        rank = self.rank(values[0])
        axis %= rank
        v0 = self.info(values[0])
        shape = list(v0.shape)
        sizes = [self.info(v).shape[axis] for v in values]
        shape[axis] = None if None in sizes else sum(sizes)
        if rank == 4 and any(self.info(v).nchw for v in values):
            y = self.node("Concat", [self.nchw(v) for v in values], axis=(0, 2, 3, 1)[axis])
            return _Value(y, True, tuple(shape), v0.dtype)
        return _Value(self.node("Concat", [self.tf(v) for v in values], axis=axis), False, tuple(shape), v0.dtype)

    def op_transpose(self, node, ins):
        perm = [int(p) for p in self.value(ins[1])]
        v = self.info(ins[0])
        shape = tuple(v.shape[p] for p in perm)
        if v.nchw and perm == _NHWC_TO_NCHW:  # NCHW data handed to TF as NCHW: nothing to do
            return _Value(v.name, False, shape, v.dtype)
        if not v.nchw and len(perm) == 4 and perm == _NCHW_TO_NHWC:  # TF NCHW -> NHWC: hold as NCHW
            return _Value(v.name, True, shape, v.dtype)
        return _Value(self.node("Transpose", [self.tf(ins[0])], perm=perm), False, shape, v.dtype)

    def op_pad(self, node, ins):
        v = self.info(ins[0])
        pads = self.value(ins[1]).astype(np.int64)  # [rank, 2] (begin, end)
        shape = tuple(None if d is None else d + int(p.sum()) for d, p in zip(v.shape, pads))
        if v.nchw:
            pads = pads[_NHWC_TO_NCHW]
        inputs = [v.name, self.const(np.concatenate([pads[:, 0], pads[:, 1]]), "pads")]
        if len(ins) > 2:
            inputs.append(self.const(self.value(ins[2]).astype(v.dtype), "padv"))
        return _Value(self.node("Pad", inputs, mode="constant"), v.nchw, shape, v.dtype)

    op_padv2 = op_pad

    # --- operators in TF layout -----------------------------------------------------------

    def op_shape(self, node, ins):
        v = self.info(ins[0])
        dtype = _attr(node, "out_type", np.dtype(np.int32))
        if None not in v.shape:
            self.known[f"{node['name']}:0"] = np.array(v.shape, dtype)
            return self.info(f"{node['name']}:0")
        s = self.node("Shape", [v.name])
        if v.nchw:
            s = self.node("Gather", [s, self.const(np.array(_NCHW_TO_NHWC, np.int64), "perm")], axis=0)
        return _Value(self.node("Cast", [s], to=_ONNX_TYPES[dtype]), False, (len(v.shape),), dtype)

    def op_size(self, node, ins):
        dtype = _attr(node, "out_type", np.dtype(np.int32))
        return _Value(self.node("Cast", [self.node("Size", [self.info(ins[0]).name])], to=_ONNX_TYPES[dtype]),
                      False, (), dtype)

    def op_reshape(self, node, ins):
        v = self.info(ins[0])
        target = self.info(ins[1])
        if ins[1] in self.known:
            dims = [int(d) for d in self.known[ins[1]]]
            shape = tuple(None if d == -1 else d for d in dims)
        else:
            if target.shape[0] is None:
                raise ConversionError(f"{node['name']}: the rank of the reshape target is unknown")
            shape = (None,) * target.shape[0]
        return _Value(self.node("Reshape", [self.tf(ins[0]), self.ints(ins[1], "shape")], allowzero=1),
                      False, shape, v.dtype)

    def op_squeeze(self, node, ins):
        v = self.info(ins[0])
        axes = [a % len(v.shape) for a in _attr(node, "squeeze_dims", [])]
        if not axes:
            axes = [k for k, d in enumerate(v.shape) if d == 1]
            if len(axes) != sum(d in (1, None) for d in v.shape):
                raise ConversionError(f"{node['name']}: Squeeze without axes on an unknown shape")
        shape = tuple(d for k, d in enumerate(v.shape) if k not in axes)
        return _Value(self.node("Squeeze", [self.tf(ins[0]), self.const(np.array(axes, np.int64), "axes")]),
                      False, shape, v.dtype)

    def op_expanddims(self, node, ins):
        v = self.info(ins[0])
        axis = int(self.value(ins[1])) % (len(v.shape) + 1)
        shape = v.shape[:axis] + (1,) + v.shape[axis:]
        return _Value(self.node("Unsqueeze", [self.tf(ins[0]), self.const(np.array([axis], np.int64), "axes")]),
                      False, shape, v.dtype)

    def op_pack(self, node, ins):
        v = self.info(ins[0])
        axis = _attr(node, "axis", 0) % (len(v.shape) + 1)
        ax = self.const(np.array([axis], np.int64), "axes")
        parts = [self.node("Unsqueeze", [self.tf(i), ax]) for i in ins]
        shape = _broadcast(*[self.info(i).shape for i in ins])
        shape = shape[:axis] + (len(ins),) + shape[axis:]
        return _Value(self.node("Concat", parts, axis=axis), False, shape, v.dtype)

    def _split(self, node, x: str, axis: int, sizes: list[int] | None, count: int, squeeze: bool):
        v = self.info(x)
        axis %= len(v.shape)
        outs = [self.fresh("split") for _ in range(count)]
        inputs = [self.tf(x)] + ([self.const(np.array(sizes, np.int64), "sizes")] if sizes else [])
        self.nodes.append(helper.make_node("Split", inputs, outs, name=self.fresh("n"), axis=axis))
        values = []
        for k, o in enumerate(outs):
            shape = list(v.shape)
            if squeeze:
                del shape[axis]
                o = self.node("Squeeze", [o, self.const(np.array([axis], np.int64), "axes")])
            else:
                shape[axis] = sizes[k] if sizes else (None if shape[axis] is None else shape[axis] // count)
            values.append(_Value(o, False, tuple(shape), v.dtype))
        return values

    def op_unpack(self, node, ins):
        return self._split(node, ins[0], _attr(node, "axis", 0), None, _attr(node, "num"), squeeze=True)

    def op_split(self, node, ins):
        return self._split(node, ins[1], int(self.value(ins[0])), None, _attr(node, "num_split"), squeeze=False)

    def op_splitv(self, node, ins):
        sizes = [int(s) for s in self.value(ins[1])]
        if -1 in sizes:
            total = self.info(ins[0]).shape[int(self.value(ins[2]))]
            if total is None:
                raise ConversionError(f"{node['name']}: SplitV with -1 on an unknown dimension")
            sizes[sizes.index(-1)] = total - (sum(sizes) + 1)
        return self._split(node, ins[0], int(self.value(ins[2])), sizes, len(sizes), squeeze=False)

    def op_stridedslice(self, node, ins):
        v = self.info(ins[0])
        begin, end, strides = (self.value(i).astype(np.int64) for i in ins[1:4])
        masks = {k: _attr(node, k, 0) for k in ("begin_mask", "end_mask", "ellipsis_mask", "new_axis_mask",
                                                   "shrink_axis_mask")}
        if masks["ellipsis_mask"]:
            raise ConversionError(f"{node['name']}: StridedSlice with an ellipsis is not supported")
        starts, ends, axes, steps, squeeze, unsqueeze = [], [], [], [], [], []
        shape = list(v.shape)
        dim = out = 0
        for k in range(len(begin)):
            bit = 1 << k
            if masks["new_axis_mask"] & bit:
                unsqueeze.append(out)
                out += 1
                continue
            b, e, s = int(begin[k]), int(end[k]), int(strides[k])
            if masks["shrink_axis_mask"] & bit:
                starts.append(b), ends.append(b + 1 if b != -1 else _INT64_MAX), axes.append(dim), steps.append(1)
                squeeze.append(dim)
            else:
                if masks["begin_mask"] & bit:
                    b = 0 if s > 0 else _INT64_MAX
                if masks["end_mask"] & bit:
                    e = _INT64_MAX if s > 0 else _INT64_MIN
                if not (b == 0 and e == _INT64_MAX and s == 1):
                    starts.append(b), ends.append(e), axes.append(dim), steps.append(s)
                    if shape[dim] is not None:
                        shape[dim] = len(range(shape[dim])[slice(b, e, s)])
                out += 1
            dim += 1
        y = self.tf(ins[0])
        if axes:
            y = self.node("Slice", [y, *(self.const(np.array(a, np.int64), "ss") for a in (starts, ends, axes, steps))])
        if squeeze:
            y = self.node("Squeeze", [y, self.const(np.array(squeeze, np.int64), "axes")])
            shape = [d for k, d in enumerate(shape) if k not in squeeze]
        if unsqueeze:
            y = self.node("Unsqueeze", [y, self.const(np.array(unsqueeze, np.int64), "axes")])
            for a in unsqueeze:
                shape.insert(a, 1)
        return _Value(y, False, tuple(shape), v.dtype)

    def op_range(self, node, ins):
        dtype = self.info(ins[0]).dtype
        size = None
        if all(i in self.known for i in ins):
            size = len(np.arange(*[self.known[i] for i in ins]))
        return _Value(self.node("Range", [self.tf(i) for i in ins]), False, (size,), dtype)

    def op_fill(self, node, ins):
        rank = self.info(ins[0]).shape[0]
        shape = tuple(int(d) for d in self.known[ins[0]]) if ins[0] in self.known else (None,) * rank
        return _Value(self.node("Expand", [self.tf(ins[1]), self.ints(ins[0], "shape")]), False, shape,
                      self.info(ins[1]).dtype)

    def op_tile(self, node, ins):
        v = self.info(ins[0])
        reps = self.known.get(ins[1])
        shape = tuple(None if d is None or reps is None else d * int(r) for d, r in
                      zip(v.shape, reps if reps is not None else [None] * len(v.shape)))
        return _Value(self.node("Tile", [self.tf(ins[0]), self.ints(ins[1], "reps")]), False, shape, v.dtype)

    def op_topkv2(self, node, ins):
        v = self.info(ins[0])
        k = int(self.value(ins[1]))
        values, indices = self.fresh("topk"), self.fresh("topk_i")
        self.nodes.append(helper.make_node("TopK", [self.tf(ins[0]), self.const(np.array([k], np.int64), "k")],
                                           [values, indices], name=self.fresh("n"), axis=-1, largest=1,
                                           sorted=1))
        shape = v.shape[:-1] + (k,)
        return [_Value(values, False, shape, v.dtype),
                _Value(self.node("Cast", [indices], to=TensorProto.INT32), False, shape, np.dtype(np.int32))]

    def op_argmax(self, node, ins):
        v = self.info(ins[0])
        axis = int(self.value(ins[1])) % len(v.shape)
        dtype = _attr(node, "output_type", np.dtype(np.int64))
        y = self.node("ArgMax", [self.tf(ins[0])], axis=axis, keepdims=0)
        if dtype != np.int64:
            y = self.node("Cast", [y], to=_ONNX_TYPES[dtype])
        return _Value(y, False, v.shape[:axis] + v.shape[axis + 1:], dtype)

    def _reduce(self, node, ins, op: str):
        v = self.info(ins[0])
        axes = sorted({int(a) % len(v.shape) for a in np.atleast_1d(self.value(ins[1]))})
        keep = _attr(node, "keep_dims", False)
        shape = tuple(1 if k in axes else d for k, d in enumerate(v.shape) if keep or k not in axes)
        if op == "ReduceSum":  # axes is an input from opset 13
            y = self.node(op, [self.tf(ins[0]), self.const(np.array(axes, np.int64), "axes")], keepdims=int(keep))
        else:                  # axes is still an attribute in opset 17
            y = self.node(op, [self.tf(ins[0])], axes=axes, keepdims=int(keep))
        return _Value(y, False, shape, v.dtype)

    def op_max(self, node, ins):
        return self._reduce(node, ins, "ReduceMax")

    def op_min(self, node, ins):
        return self._reduce(node, ins, "ReduceMin")

    def op_sum(self, node, ins):
        return self._reduce(node, ins, "ReduceSum")

    def op_mean(self, node, ins):
        return self._reduce(node, ins, "ReduceMean")

    def op_gathernd(self, node, ins):
        params, indices = self.info(ins[0]), self.info(ins[1])
        depth = indices.shape[-1]
        if depth is None:
            raise ConversionError(f"{node['name']}: GatherNd with an unknown index depth")
        shape = indices.shape[:-1] + params.shape[depth:]
        return _Value(self.node("GatherND", [self.tf(ins[0]), self.ints(ins[1])]), False, shape, params.dtype)

    def op_select(self, node, ins):
        cond, x, y = (self.info(i) for i in ins)
        if node["op"] == "Select" and len(cond.shape) != len(x.shape):  # Select's vector condition picks rows
            raise ConversionError(f"{node['name']}: Select with a condition of lower rank is not supported")
        return _Value(self.node("Where", [self.tf(i) for i in ins]), False, _broadcast(cond.shape, x.shape, y.shape),
                      x.dtype)

    op_selectv2 = op_select

def convert(model_json: str | os.PathLike, float_inputs: bool = False, keep_float16: bool = True) -> onnx.ModelProto:
    """The TF.js graph model at `model_json` as an ONNX model.

    Inputs and outputs keep their TF.js layouts, names (without ":0") and open dimensions.
    `float_inputs` turns integer inputs whose only consumers are Casts to float into float32
    inputs (the casts disappear), e.g. MoveNet's int32 RGB image. `keep_float16` stores the
    weights that TF.js holds in float16 as float16 initializers, each read through a Cast to
    float32 that onnxruntime folds when it loads the model: half the file, the same numbers.
    """
    spec, weights = load_tfjs(model_json, keep_float16)
    nodes = spec["modelTopology"]["node"]
    b = _Builder(weights)
    consumers: dict[str, list[dict]] = {}
    for n in nodes:
        for i in n.get("input", []):
            consumers.setdefault(i.lstrip("^").split(":")[0], []).append(n)

    graph_inputs = []
    for n in nodes:
        if n["op"] != "Placeholder":
            continue
        dtype = _attr(n, "dtype")
        shape = _attr(n, "shape")
        if float_inputs and dtype.kind != "f":
            users = consumers.get(n["name"], [])
            if not users or any(u["op"] != "Cast" or _attr(u, "DstT") != np.float32 for u in users):
                raise ConversionError(f"input {n['name']} has consumers other than Casts to float")
            dtype = np.dtype(np.float32)
        dims = [("N", "H", "W", "C")[k] if d < 0 and len(shape) == 4 else (f"d{k}" if d < 0 else d)
                for k, d in enumerate(shape)]
        graph_inputs.append(helper.make_tensor_value_info(n["name"], _ONNX_TYPES[dtype], dims))
        b.values[f"{n['name']}:0"] = _Value(n["name"], False, tuple(None if d < 0 else d for d in shape), dtype)

    for n in nodes:
        if n["op"] != "Placeholder":
            b.emit(n)

    signature = spec.get("signature", {}).get("outputs", {})
    declared = {_ref(o["name"]): [int(d.get("size", -1)) for d in o.get("tensorShape", {}).get("dim", [])]
                for o in signature.values()}
    if not declared:
        declared = {_ref(n["name"]): [] for n in nodes
                    if n["name"] not in consumers and n["op"] not in ("Const", "Placeholder")}
    graph_outputs = []
    for ref in sorted(declared):
        name = ref.split(":")[0]
        v = b.info(ref)
        b.node("Identity", [b.tf(ref)], name)
        sig = declared[ref] if len(declared[ref]) == len(v.shape) else [-1] * len(v.shape)
        dims = [d if d is not None else s if s > 0 else f"{name}_d{k}" for k, (d, s) in enumerate(zip(v.shape, sig))]
        graph_outputs.append(helper.make_tensor_value_info(name, _ONNX_TYPES[v.dtype], dims))

    graph = helper.make_graph(b.nodes, "posecam", graph_inputs, graph_outputs, b.initializers)
    return finish_model(graph, "posecam.export.convert.tfjs_onnx")
