"""Feature extractors: level shapes, torchvision-layout weight loading, offline extractors."""

import pytest
import torch

from mistyle.conventions import OFFLINE_EXTRACTOR
from mistyle.model.features import (
    FilterBankFeatures,
    VGG16Features,
    make_extractor,
    random_vgg16,
    vgg16_weights_path,
)


@pytest.mark.parametrize("extractor", [random_vgg16(), FilterBankFeatures()], ids=["vgg16-random", "filterbank"])
def test_four_levels_at_halving_resolutions(extractor):
    images = torch.rand(2, 3, 32, 40)
    levels = extractor(images)
    assert [tuple(level.shape[2:]) for level in levels] == [(32, 40), (16, 20), (8, 10), (4, 5)]
    assert [level.shape[1] for level in levels] == list(extractor.channels)
    assert all(torch.isfinite(level).all() for level in levels)


def torchvision_like_state_dict(seed: int = 5) -> dict:
    """A state dict with torchvision VGG16's keys and shapes (features up to 28, plus a classifier)."""
    reference = random_vgg16(seed)
    state = {key: value.clone() for key, value in reference.state_dict().items() if key.startswith("features.")}
    for index, (cin, cout) in zip((24, 26, 28), ((512, 512),) * 3):
        state[f"features.{index}.weight"] = torch.randn(cout, cin, 3, 3)
        state[f"features.{index}.bias"] = torch.zeros(cout)
    state["classifier.0.weight"] = torch.randn(8, 8)
    return state


def test_loads_torchvision_weights_from_the_environment(tmp_path, monkeypatch):
    state = torchvision_like_state_dict()
    path = tmp_path / "vgg16-397923af.pth"
    torch.save(state, path)
    monkeypatch.setenv("MISTYLE_VGG16_WEIGHTS", str(path))
    model = make_extractor("auto")
    assert model.name == "vgg16-imagenet"
    torch.testing.assert_close(model.features[0].weight, state["features.0.weight"])
    images = torch.rand(1, 3, 16, 16)
    torch.testing.assert_close(model(images)[3], random_vgg16(5)(images)[3])


def test_bad_weights_and_missing_weights_are_clear(tmp_path, monkeypatch):
    broken = tmp_path / "broken.pth"
    broken.write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match="Cannot read VGG16 weights"):
        make_extractor("vgg16", weights=broken)
    wrong = tmp_path / "wrong.pth"
    state = torchvision_like_state_dict()
    state["features.0.weight"] = torch.zeros(64, 4, 3, 3)
    torch.save(state, wrong)
    with pytest.raises(ValueError, match="shape"):
        make_extractor("vgg16", weights=wrong)
    with pytest.raises(ValueError, match="does not exist"):
        vgg16_weights_path(tmp_path / "none.pth")
    monkeypatch.delenv("MISTYLE_VGG16_WEIGHTS", raising=False)
    monkeypatch.setattr(torch.hub, "get_dir", lambda: str(tmp_path / "hub"))
    with pytest.raises(ValueError, match="MISTYLE_VGG16_WEIGHTS"):
        make_extractor("vgg16")
    assert make_extractor("auto").name == OFFLINE_EXTRACTOR


def test_extractors_pass_gradients_to_the_image():
    images = torch.rand(1, 3, 16, 16, requires_grad=True)
    for extractor in (random_vgg16(), FilterBankFeatures()):
        sum(level.mean() for level in extractor(images)).backward()
        assert torch.isfinite(images.grad).all() and images.grad.abs().sum() > 0
        images.grad = None
    assert not any(p.requires_grad for p in VGG16Features().parameters())
