"""The paper's network in torch: ResNet-U, its backbones, and checkpoints (weights_only)."""
