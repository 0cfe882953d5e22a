"""The structure metric (``mistyle.objective.structure``) is validated before the benchmark trusts it.

Each held-out style is split into a checkerboard of 64-pixel tiles: the even tiles are the style the
metric measures against, the odd tiles a held-out crop of it (paintings are not stationary, so a crop
from one half can be unlike the other half; the checkerboard holds out pieces from everywhere). On
every held-out style the held-out crop must be closer than
* the same tiles with their pixels shuffled in 8x8 blocks (colours and small patches kept, the
  arrangement gone);
* smooth colour noise with the crop's own colours (each channel's values re-ordered along a blurred
  noise field: the style's palette, no structure);
* the held-out tiles of every other held-out style.
And a crop's value must not depend on the background it is shown over, only on the mask.
"""

from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from mistyle.files import load_style
from mistyle.objective.structure import statistics_distance, structure_distance, structure_statistics

STYLES = sorted((Path(__file__).resolve().parents[1] / "mistyle" / "data" / "heldout_styles").glob("*.jpg"))
TILE = 64


def checkerboard(image: np.ndarray) -> tuple[list, list]:
    rows, columns = image.shape[0] // TILE, image.shape[1] // TILE
    pieces = {0: [], 1: []}
    for i in range(rows):
        for j in range(columns):
            pieces[(i + j) % 2].append(image[i * TILE : (i + 1) * TILE, j * TILE : (j + 1) * TILE])
    return pieces[0], pieces[1]


def block_shuffled(image: np.ndarray, rng, block: int = 8) -> np.ndarray:
    h, w = image.shape[0] // block, image.shape[1] // block
    blocks = (
        image[: h * block, : w * block]
        .reshape(h, block, w, block, 3)
        .transpose(0, 2, 1, 3, 4)
        .reshape(-1, block, block, 3)
    )
    blocks = blocks[rng.permutation(len(blocks))]
    return blocks.reshape(h, w, block, block, 3).transpose(0, 2, 1, 3, 4).reshape(h * block, w * block, 3)


def palette_noise(image: np.ndarray, rng, sigma: float = 4.0) -> np.ndarray:
    out = np.empty_like(image)
    for channel in range(3):
        field = ndimage.gaussian_filter(rng.normal(size=image.shape[:2]), sigma)
        values = np.empty(field.size, np.float32)
        values[np.argsort(field.ravel())] = np.sort(image[..., channel].ravel())
        out[..., channel] = values.reshape(image.shape[:2])
    return out


@pytest.fixture(scope="module")
def split():
    return {path.stem: checkerboard(load_style(path)) for path in STYLES}


def test_held_out_crops_beat_shuffled_blocks_palette_noise_and_other_styles(split):
    rng = np.random.default_rng(0)
    references = {name: structure_statistics(pieces[0], None) for name, pieces in split.items()}
    crops = {name: structure_statistics(pieces[1], None) for name, pieces in split.items()}
    failures = []
    for name, (_, held_out) in split.items():
        own = statistics_distance(crops[name], references[name])
        shuffled = statistics_distance(
            structure_statistics([block_shuffled(piece, rng) for piece in held_out], None), references[name]
        )
        noise = statistics_distance(
            structure_statistics([palette_noise(piece, rng) for piece in held_out], None), references[name]
        )
        others = {other: statistics_distance(crops[other], references[name]) for other in split if other != name}
        closest = min(others, key=others.get)
        if not (own < shuffled and own < noise and own < others[closest]):
            failures.append(
                f"{name}: crop {own:.3f}, shuffled {shuffled:.3f}, noise {noise:.3f}, {closest} {others[closest]:.3f}"
            )
    assert len(split) == 14 and not failures, failures


def test_the_background_does_not_count(rng):
    style = load_style(STYLES[0])
    crop = style[40:140, 60:160]
    mask = np.zeros((160, 160), bool)
    mask[30:130, 30:130] = True
    values = []
    for background in (np.zeros((160, 160, 3)), np.ones((160, 160, 3)), rng.random((160, 160, 3))):
        image = background.astype(np.float32)
        image[30:130, 30:130] = crop
        values.append(structure_distance([image], [mask], style))
    assert values[0] == pytest.approx(values[1], abs=1e-6) and values[0] == pytest.approx(values[2], abs=1e-6)
    # Without the mask the frame's edges and the background become structure.
    assert abs(structure_distance([np.ones((160, 160, 3), np.float32)], None, style) - values[0]) > 0.05


def test_too_small_a_mask_is_nan():
    style = load_style(STYLES[1])
    mask = np.zeros((64, 64), bool)
    mask[30:34, 30:34] = True
    assert np.isnan(structure_distance([style[:64, :64]], [mask], style))
