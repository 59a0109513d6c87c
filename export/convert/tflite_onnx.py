"""A small TFLite -> ONNX converter for the BlazePose networks (detector and landmark models).

The flatbuffer is parsed with the `tflite` package and rebuilt with `onnx.helper`, op by op.
TFLite works in NHWC; the ONNX graph works in NCHW inside, transposing once at the input and
back at 4-D outputs and before reshapes. Weights that TFLite stores sparse (DENSIFY) or in
fp16 (DEQUANTIZE) are read by running the model once in LiteRT with every intermediate tensor
kept and no XNNPACK delegate (with the delegate those tensors read back as zeros).

The batch axis is dynamic. Saved with IR version 9 / opset 17 (onnxruntime 1.31 refuses IR 14).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import onnx
import tflite
from onnx import TensorProto, helper, numpy_helper

OPSET = 17
IR_VERSION = 9
_OP_NAMES = {v: k for k, v in vars(tflite.BuiltinOperator).items() if not k.startswith("_")}
_CONSTANT_PRODUCERS = {"DEQUANTIZE", "DENSIFY"}
_NHWC_TO_NCHW = [0, 3, 1, 2]
_NCHW_TO_NHWC = [0, 2, 3, 1]


class ConversionError(ValueError):
    """The TFLite model uses something this converter does not handle."""


def _options(op, cls):
    table = op.BuiltinOptions()
    opts = cls()
    opts.Init(table.Bytes, table.Pos)
    return opts


def _same_pads(in_hw: tuple[int, int], out_hw: tuple[int, int], kernel: tuple[int, int],
               stride: tuple[int, int], dilation: tuple[int, int] = (1, 1)) -> list[int]:
    """TensorFlow 'SAME' padding as ONNX pads [top, left, bottom, right] (extra at the end)."""
    begin, end = [], []
    for i, o, k, s, d in zip(in_hw, out_hw, kernel, stride, dilation):
        total = max((o - 1) * s + (k - 1) * d + 1 - i, 0)
        begin.append(total // 2)
        end.append(total - total // 2)
    return begin + end


def read_constants(path: str | os.PathLike, indices: list[int]) -> dict[int, np.ndarray]:
    """Values of the given tensors after one LiteRT run (densified and dequantized weights)."""
    from ai_edge_litert.interpreter import Interpreter, OpResolverType

    interp = Interpreter(model_path=str(path), experimental_preserve_all_tensors=True,
                         experimental_op_resolver_type=OpResolverType.BUILTIN_WITHOUT_DEFAULT_DELEGATES)
    interp.allocate_tensors()
    for d in interp.get_input_details():
        interp.set_tensor(d["index"], np.zeros(d["shape"], d["dtype"]))
    interp.invoke()
    return {i: np.array(interp.get_tensor(i)) for i in indices}


@dataclass
class _Value:
    name: str
    nchw: bool        # a 4-D tensor held in NCHW inside the ONNX graph


class _Builder:
    """Walks the TFLite operators in order and emits ONNX nodes."""

    def __init__(self, graph, model, constants: dict[int, np.ndarray]):
        self.g = graph
        self.model = model
        self.constants = constants
        self.values: dict[int, _Value] = {}
        self.nodes: list[onnx.NodeProto] = []
        self.initializers: list[onnx.TensorProto] = []
        self._count = 0

    def fresh(self, hint: str) -> str:
        self._count += 1
        return f"{hint}_{self._count}"

    def const(self, array: np.ndarray, hint: str) -> str:
        name = self.fresh(hint)
        self.initializers.append(numpy_helper.from_array(np.ascontiguousarray(array), name))
        return name

    def node(self, op: str, inputs: list[str], output: str | None = None, **attrs) -> str:
        output = output or self.fresh(op.lower())
        self.nodes.append(helper.make_node(op, inputs, [output], name=self.fresh("n"), **attrs))
        return output

    def shape(self, index: int) -> list[int]:
        return [int(s) for s in self.g.Tensors(index).ShapeAsNumpy()]

    def tensor_name(self, index: int) -> str:
        return self.g.Tensors(index).Name().decode()

    def weight(self, index: int) -> np.ndarray:
        if index not in self.constants:
            raise ConversionError(f"tensor {self.tensor_name(index)} is not a constant")
        return self.constants[index].astype(np.float32)

    def nchw(self, index: int) -> str:
        v = self.values[index]
        return v.name if v.nchw or len(self.shape(index)) != 4 else self.node("Transpose", [v.name], perm=_NHWC_TO_NCHW)

    def nhwc(self, index: int) -> str:
        v = self.values[index]
        return self.node("Transpose", [v.name], perm=_NCHW_TO_NHWC) if v.nchw else v.name

    def activation(self, name: str, fused: int) -> str:
        act = tflite.ActivationFunctionType
        if fused == act.NONE:
            return name
        if fused == act.RELU:
            return self.node("Relu", [name])
        if fused == act.RELU6:
            return self.node("Clip", [name, self.const(np.float32(0), "zero"), self.const(np.float32(6), "six")])
        raise ConversionError(f"fused activation {fused} is not supported")

    def emit(self, kind: str, op) -> None:
        ins = [op.Inputs(i) for i in range(op.InputsLength())]
        out = op.Outputs(0)
        method = getattr(self, "op_" + kind.lower(), None)
        if method is None:
            raise ConversionError(f"TFLite operator {kind} is not supported")
        name, nchw = method(op, ins, out)
        self.values[out] = _Value(name, nchw)

    # --- operators -------------------------------------------------------------------------

    def _conv(self, op, ins, out, depthwise: bool):
        o = _options(op, tflite.DepthwiseConv2DOptions if depthwise else tflite.Conv2DOptions)
        w = self.weight(ins[1])
        if depthwise:  # [1, kh, kw, C*m] -> [C*m, 1, kh, kw]
            w = w.transpose(3, 0, 1, 2)
        else:          # [O, kh, kw, I] -> [O, I, kh, kw]
            w = w.transpose(0, 3, 1, 2)
        kernel = w.shape[2:]
        stride = (o.StrideH(), o.StrideW())
        dilation = (o.DilationHFactor(), o.DilationWFactor())
        in_shape, out_shape = self.shape(ins[0]), self.shape(out)
        pads = (_same_pads(in_shape[1:3], out_shape[1:3], kernel, stride, dilation)
                if o.Padding() == tflite.Padding.SAME else [0, 0, 0, 0])
        inputs = [self.nchw(ins[0]), self.const(w, "w")]
        if len(ins) > 2 and ins[2] >= 0:
            inputs.append(self.const(self.weight(ins[2]), "b"))
        y = self.node("Conv", inputs, kernel_shape=list(kernel), strides=list(stride), dilations=list(dilation),
                      pads=pads, group=in_shape[3] if depthwise else 1)
        return self.activation(y, o.FusedActivationFunction()), True

    def op_conv_2d(self, op, ins, out):
        return self._conv(op, ins, out, depthwise=False)

    def op_depthwise_conv_2d(self, op, ins, out):
        return self._conv(op, ins, out, depthwise=True)

    def op_add(self, op, ins, out):
        o = _options(op, tflite.AddOptions)
        four_d = len(self.shape(out)) == 4
        operands = []
        for i in ins:
            if i in self.constants:
                c = self.weight(i)
                if four_d and c.ndim >= 1:  # NHWC broadcast constant -> NCHW
                    c = c.reshape((1,) * (4 - c.ndim) + c.shape).transpose(_NHWC_TO_NCHW)
                operands.append(self.const(c, "c"))
            else:
                operands.append(self.nchw(i) if four_d else self.values[i].name)
        return self.activation(self.node("Add", operands), o.FusedActivationFunction()), four_d

    def op_pad(self, op, ins, out):
        pads = self.weight(ins[1]).astype(np.int64)  # [4, 2] NHWC (begin, end)
        pads = pads[_NHWC_TO_NCHW]
        return self.node("Pad", [self.nchw(ins[0]), self.const(np.concatenate([pads[:, 0], pads[:, 1]]), "pads")],
                         mode="constant"), True

    def op_max_pool_2d(self, op, ins, out):
        o = _options(op, tflite.Pool2DOptions)
        kernel, stride = (o.FilterHeight(), o.FilterWidth()), (o.StrideH(), o.StrideW())
        pads = (_same_pads(self.shape(ins[0])[1:3], self.shape(out)[1:3], kernel, stride)
                if o.Padding() == tflite.Padding.SAME else [0, 0, 0, 0])
        y = self.node("MaxPool", [self.nchw(ins[0])], kernel_shape=list(kernel), strides=list(stride), pads=pads)
        return self.activation(y, o.FusedActivationFunction()), True

    def op_logistic(self, op, ins, out):
        v = self.values[ins[0]]
        return self.node("Sigmoid", [v.name]), v.nchw

    def op_resize_bilinear(self, op, ins, out):
        o = _options(op, tflite.ResizeBilinearOptions)
        mode = "align_corners" if o.AlignCorners() else "half_pixel" if o.HalfPixelCenters() else "asymmetric"
        (_, ih, iw, _), (_, oh, ow, _) = self.shape(ins[0]), self.shape(out)
        scales = self.const(np.array([1, 1, oh / ih, ow / iw], np.float32), "scales")
        return self.node("Resize", [self.nchw(ins[0]), "", scales], mode="linear",
                         coordinate_transformation_mode=mode), True

    def op_depth_to_space(self, op, ins, out):
        o = _options(op, tflite.DepthToSpaceOptions)
        return self.node("DepthToSpace", [self.nchw(ins[0])], blocksize=o.BlockSize(), mode="DCR"), True

    def op_concatenation(self, op, ins, out):
        o = _options(op, tflite.ConcatenationOptions)
        rank = len(self.shape(out))
        axis = o.Axis() % rank
        if rank == 4:
            axis = (0, 2, 3, 1)[axis]  # NHWC axis -> NCHW axis
            operands = [self.nchw(i) for i in ins]
        else:
            operands = [self.values[i].name for i in ins]
        y = self.node("Concat", operands, axis=axis)
        return self.activation(y, o.FusedActivationFunction()), rank == 4

    def op_reshape(self, op, ins, out):
        shape = self.shape(out)
        target = self.const(np.array([-1] + shape[1:], np.int64), "shape")  # first axis is the batch
        y = self.node("Reshape", [self.nhwc(ins[0]), target])
        if len(shape) == 4:
            return self.node("Transpose", [y], perm=_NHWC_TO_NCHW), True
        return y, False


def convert(path: str | os.PathLike, outputs: list[str] | None = None) -> onnx.ModelProto:
    """The TFLite model at `path` as an ONNX model (NHWC input, dynamic batch).

    `outputs` keeps only these graph outputs (by TFLite name) and drops the operators that only
    fed the others, e.g. BlazePose's segmentation mask and heatmaps, which posecam does not use.
    """
    buf = open(path, "rb").read()
    model = tflite.Model.GetRootAsModel(buf, 0)
    if model.SubgraphsLength() != 1:
        raise ConversionError("only single-graph TFLite models are supported")
    g = model.Subgraphs(0)
    codes = [model.OperatorCodes(i) for i in range(model.OperatorCodesLength())]

    def kind(op) -> str:
        code = codes[op.OpcodeIndex()]
        return _OP_NAMES[max(code.BuiltinCode(), code.DeprecatedBuiltinCode())]

    ops = [g.Operators(i) for i in range(g.OperatorsLength())]
    constant_ids = {op.Outputs(0) for op in ops if kind(op) in _CONSTANT_PRODUCERS}
    for i in range(g.TensorsLength()):
        t = g.Tensors(i)
        if model.Buffers(t.Buffer()).DataLength() > 0:
            constant_ids.add(i)
    builder = _Builder(g, model, read_constants(path, sorted(constant_ids)))

    graph_inputs = []
    for k in range(g.InputsLength()):
        idx = g.Inputs(k)
        name, shape = builder.tensor_name(idx), builder.shape(idx)
        graph_inputs.append(helper.make_tensor_value_info(name, TensorProto.FLOAT, ["N", *shape[1:]]))
        builder.values[idx] = _Value(name, False)
    for op in ops:
        if kind(op) not in _CONSTANT_PRODUCERS:
            builder.emit(kind(op), op)

    graph_outputs = []
    for k in range(g.OutputsLength()):
        idx = g.Outputs(k)
        name, shape = builder.tensor_name(idx), builder.shape(idx)
        if outputs is not None and name not in outputs:
            continue
        builder.node("Identity", [builder.nhwc(idx)], name)
        graph_outputs.append(helper.make_tensor_value_info(name, TensorProto.FLOAT, ["N", *shape[1:]]))

    graph = helper.make_graph(builder.nodes, "posecam", graph_inputs, graph_outputs, builder.initializers)
    return finish_model(graph, "posecam.export.convert.tflite_onnx")


def finish_model(graph: onnx.GraphProto, producer: str) -> onnx.ModelProto:
    """The model around a converted graph: opset 17, IR 9 (what onnxruntime 1.31 reads), nodes
    that feed no output pruned, checked."""
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)], producer_name=producer)
    model.ir_version = IR_VERSION
    model = _prune(model)
    onnx.checker.check_model(model)
    return model


def _prune(model: onnx.ModelProto) -> onnx.ModelProto:
    """Drop nodes and initializers that no graph output depends on."""
    g = model.graph
    needed = {o.name for o in g.output}
    keep = []
    for node in reversed(g.node):
        if any(o in needed for o in node.output):
            keep.append(node)
            needed.update(i for i in node.input if i)
    keep.reverse()
    del g.node[:]
    g.node.extend(keep)
    inits = [t for t in g.initializer if t.name in needed]
    del g.initializer[:]
    g.initializer.extend(inits)
    return model
