"""SKPN, its feature extractors, losses and metrics, datasets and the training loop."""
