"""A style is resolved once where it enters (``mistyle.style.Style``), and every stage takes that value."""

from pathlib import Path

import numpy as np
import pytest

from mistyle.style import Style, style_target

ROOT = Path(__file__).resolve().parents[1]
MARBLE = ROOT / "examples" / "style_marble.png"
WAVE = ROOT / "mistyle" / "data" / "heldout_styles" / "hokusai_great_wave.jpg"


def test_a_style_of_a_path_an_array_and_a_mix():
    one = Style.of(MARBLE)
    assert one.names == ("style_marble.png",) and one.weights == (1.0,) and not one.is_mix
    assert one.target is one.images[0] and one.describe() == "style_marble.png"
    array = Style.of(one.images[0])
    assert array.names == ("an image",) and np.array_equal(array.images[0], one.images[0])
    mix = Style.of([(MARBLE, 3.0), (WAVE, 1.0)])
    assert mix.is_mix and mix.describe() == "0.75 x style_marble.png + 0.25 x hokusai_great_wave.jpg"
    assert np.array_equal(mix.target, style_target(list(mix.images), [3.0, 1.0]))
    assert mix.target.shape[0] == 256 and mix.target.shape[1] == 512  # a strip each, widths by weight
    assert Style.of(mix) is mix and mix.target is mix.target  # taken as it is; the mosaic made once


@pytest.mark.parametrize(
    "given, message",
    [
        ([(MARBLE, -1.0)], "weights must be >= 0"),
        ([MARBLE, WAVE], "not \\(style, weight\\) pairs"),
        (ROOT / "missing.png", "does not exist"),
    ],
)
def test_a_bad_style_is_one_clear_error(given, message):
    with pytest.raises(ValueError, match=message):
        Style.of(given)


def test_names_must_match_the_pictures():
    with pytest.raises(ValueError, match="needs as many names"):
        Style.of([(MARBLE, 1.0), (WAVE, 1.0)], names=["one"])


def test_the_pipeline_reads_a_styles_files_once(mi, blob_density, monkeypatch):
    """The network, its colour match, the look's fit and its colour match all take the one loaded style."""
    import mistyle.style
    from mistyle.pipeline import Pipeline, PipelineSettings

    loaded = []
    original = mistyle.style.load_style

    def counted(image, notes=None):
        loaded.append(image)
        return original(image, notes)

    monkeypatch.setattr(mistyle.style, "load_style", counted)
    stylized = Pipeline(PipelineSettings(look_steps=1)).stylize(blob_density, [(MARBLE, 0.5), (WAVE, 0.5)])
    assert loaded == [MARBLE, WAVE]
    assert stylized.look.meta["style"] == "0.50 x style_marble.png + 0.50 x hokusai_great_wave.jpg"
