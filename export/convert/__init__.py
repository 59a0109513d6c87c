"""Models to ONNX: TFLite and TF.js graphs (the bundled models), torch ResNet-U, int8 quantisation.

Named `convert` rather than `onnx` so that it never shadows the `onnx` package.
"""
