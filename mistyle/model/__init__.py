"""The network and what it needs to run: SKPN (SKP, VolAE, DAIN), feature extractors, configs, checkpoints.

Inference (``mistyle.api``, ``render_final``) loads a checkpoint with ``checkpoint.load_model``;
training (``mistyle.train``) builds and saves models with the same module. Nothing here imports
the training package.
"""
