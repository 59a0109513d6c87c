"""Training ResNet-U: the manifest dataset, augmentations, losses and the training loop."""
