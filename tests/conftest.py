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


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
