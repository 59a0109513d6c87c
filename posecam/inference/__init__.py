"""Pixels in, pixels out: ONNX sessions under the model contract, detectors, crops, pose models."""
