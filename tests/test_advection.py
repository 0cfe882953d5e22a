"""A look's texture carried by a sequence's velocities (``mistyle.advection``)."""

import numpy as np
import pytest
import torch

from mistyle.advection import (
    ADVECTION_PERIOD,
    Phase,
    TextureMotion,
    blend_phases,
    first_needed,
    identity_coordinates,
    sample_in_box,
)
from mistyle.look import advected_texture, stretch_texture

SHAPE = (12, 10, 24)  # (Z, Y, X)


def translation(count, step=(1.0, 0.0, 0.0)):
    """``count`` velocities moving everything ``step`` voxels a frame, components (x, y, z)."""
    return [np.broadcast_to(np.asarray(step, np.float32), SHAPE + (3,)).copy() for _ in range(count)]


def test_the_identity_reads_the_texture_as_the_fixed_look_stretches_it():
    texture = torch.randn(3, 7, 5, 9, generator=torch.Generator().manual_seed(0))
    frame = {"size": SHAPE, "window": (slice(1, 11), slice(0, 10), slice(3, 20))}
    padded = (12, 12, 20)
    fixed = stretch_texture(texture, dict(frame), padded)
    carried = advected_texture(texture, frame, padded, [Phase(identity_coordinates(SHAPE), 1.0)])
    assert carried.shape == fixed.shape == (3,) + padded
    assert torch.allclose(carried, fixed, atol=1e-5)


def test_a_translation_carries_the_texture_with_it():
    texture = torch.randn(1, *SHAPE, generator=torch.Generator().manual_seed(1))
    motion = TextureMotion(translation(6))
    assert motion.phases(0) is None  # the first frame reads the texture in place
    for frame in range(1, ADVECTION_PERIOD // 2 + 1):
        (phase,) = motion.phases(frame)  # both fields start at frame 0 until the second restarts
        assert phase.weight == pytest.approx(1.0)
        moved = sample_in_box(texture, phase.coordinates)
        # Frame t shows at x what lay at x - t at the start (the texels are the voxels here).
        assert torch.allclose(moved[..., frame:], texture[..., :-frame], atol=1e-5)


def test_fields_restart_in_turn_and_their_weights_sum_to_one():
    motion = TextureMotion(translation(3 * ADVECTION_PERIOD))

    def carried(phase):  # voxels the field has moved along x, read at the box's middle
        shift = identity_coordinates(SHAPE)[0, 0] - phase.coordinates[0, 0]
        return round(float(shift[6, 5, 12]) * SHAPE[2] / 2, 3)

    for frame in range(1, 3 * ADVECTION_PERIOD):
        phases = motion.phases(frame)
        assert phases is not None and sum(phase.weight for phase in phases) == pytest.approx(1.0)
        assert len(phases) <= 2 and all(0 < carried(phase) < ADVECTION_PERIOD for phase in phases)
    # At a restart the restarted field weighs nothing: the other, half a period old, is the frame's.
    (phase,) = motion.phases(2 * ADVECTION_PERIOD)
    assert phase.weight == pytest.approx(1.0) and carried(phase) == ADVECTION_PERIOD // 2
    with pytest.raises(ValueError, match="even number"):
        TextureMotion([], period=5)


def test_a_chunk_computes_the_fields_of_the_whole_sequence_bit_for_bit():
    rng = np.random.default_rng(2)
    velocities = [rng.normal(0, 0.7, SHAPE + (3,)).astype(np.float32) for _ in range(20)]
    whole = TextureMotion(velocities)
    fields = {frame: whole.phases(frame) for frame in range(20)}
    start = 13
    begin = first_needed(start)
    chunk = TextureMotion(velocities[begin:], begin=begin)
    for frame in range(start, 20):
        ours, theirs = chunk.phases(frame), fields[frame]
        assert [p.weight for p in ours] == [p.weight for p in theirs]
        assert all(torch.equal(a.coordinates, b.coordinates) for a, b in zip(ours, theirs))
    # Going back to an earlier frame recomputes it the same way.
    assert all(torch.equal(a.coordinates, b.coordinates) for a, b in zip(chunk.phases(start), fields[start]))
    with pytest.raises(ValueError, match="load the frames from"):
        TextureMotion(velocities[start:], begin=start).phases(start)


def test_a_blend_keeps_the_strokes_contrast():
    texture = torch.randn(3, *SHAPE, generator=torch.Generator().manual_seed(3)) + torch.tensor([1.0, 0.0, -2.0]).view(
        3, 1, 1, 1
    )
    shifted = identity_coordinates(SHAPE).clone()
    shifted[:, 0] += 10 * 2.0 / SHAPE[2]  # ten voxels along x: the two readings are unrelated
    blended = blend_phases(texture, [Phase(identity_coordinates(SHAPE), 0.5), Phase(shifted, 0.5)], SHAPE)
    spread = texture.reshape(3, -1).std(dim=1)
    # A plain average of two unrelated readings would have 1/sqrt(2) of the spread.
    assert torch.allclose(blended.reshape(3, -1).std(dim=1), spread, rtol=0.1)
    assert torch.allclose(blended.reshape(3, -1).mean(dim=1), texture.reshape(3, -1).mean(dim=1), atol=0.1)
    # Two readings of one place are that reading.
    same = blend_phases(
        texture, [Phase(identity_coordinates(SHAPE), 0.3), Phase(identity_coordinates(SHAPE), 0.7)], SHAPE
    )
    assert torch.allclose(same, texture, atol=1e-5)
