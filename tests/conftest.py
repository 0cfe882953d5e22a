import numpy as np
import pytest

from mistyle.backend import use_variant


@pytest.fixture(scope="session")
def mi():
    """Mitsuba in the CPU variant, with mistyle's integrators registered."""
    return use_variant("cpu")


@pytest.fixture(scope="session")
def blob_density():
    """A small smooth, non-cubic density (Z, Y, X) = (16, 18, 20) with empty margins."""
    from mistyle.data.procedural import pyroclastic_sphere

    return pyroclastic_sphere((16, 18, 20), radius=0.34, falloff=0.08, seed=3)


@pytest.fixture(scope="session")
def tiny_smoke(tmp_path_factory):
    """The tiny training dataset (``DATASET_SPECS["tiny"]``), generated once per session."""
    from mistyle.data.generate import generate_smoke
    from mistyle.train.dataset import DATASET_SPECS

    out = tmp_path_factory.mktemp("data") / "smoke"
    generate_smoke(DATASET_SPECS["tiny"], out, log=lambda *a: None)
    return out


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def write_tiny_checkpoint(path, seed: int = 0):
    """An untrained tiny-config SKPN in the training checkpoint format, at ``path``."""
    import torch

    from mistyle import __version__
    from mistyle.model.config import config_to_dict, load_config
    from mistyle.model.features import make_extractor
    from mistyle.model.skpn import SKPN

    config = load_config("configs/tiny.toml")
    config.model.style_channels = make_extractor("filterbank").channels
    torch.manual_seed(seed)
    torch.save(
        {
            "format": 1,
            "mistyle_version": __version__,
            "step": 0,
            "config": config_to_dict(config),
            "extractor": "filterbank",
            "density_scale": 20.0,
            "model": SKPN(config.model).state_dict(),
        },
        path,
    )
    return path


@pytest.fixture(scope="session")
def tiny_checkpoint_factory():
    """``write_tiny_checkpoint`` for tests: ``factory(path, seed=0) -> path``."""
    return write_tiny_checkpoint
