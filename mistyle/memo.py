"""Values kept for the next call with the same inputs: what a run computes again and again from one
style or one density (a metric's sorted projections of the style, its hue clusters, the colour
match's response and visible weight of a density), held by a digest of the arrays it came from, up to ``KEPT_BYTES``."""

from __future__ import annotations

import hashlib
import threading

import numpy as np

_KEPT: dict = {}
_KEPT_LOCK = threading.Lock()
KEPT_BYTES = 1 << 28
"""What ``kept`` holds at most: values computed from the last few inputs, the oldest dropped first."""


def kept(kind: str, arrays: tuple, compute) -> np.ndarray:
    """``compute()`` (an array), kept for the next call of this ``kind`` with equal ``arrays`` (equal
    dtypes, shapes and bytes; a scalar input goes in as an array too)."""
    digest = hashlib.blake2b(kind.encode(), digest_size=16)
    for array in arrays:
        array = np.ascontiguousarray(array)
        digest.update(repr((array.dtype.str, array.shape)).encode())
        digest.update(array.view(np.uint8))
    key = digest.hexdigest()
    with _KEPT_LOCK:  # callers may measure from several threads
        value = _KEPT.get(key)
    if value is not None:
        return value
    value = compute()
    with _KEPT_LOCK:
        held = sum(entry.nbytes for entry in _KEPT.values())
        while _KEPT and held + value.nbytes > KEPT_BYTES:
            held -= _KEPT.pop(next(iter(_KEPT))).nbytes
        if value.nbytes <= KEPT_BYTES:
            _KEPT[key] = value
    return value


def kept_count() -> int:
    """How many values are kept."""
    with _KEPT_LOCK:
        return len(_KEPT)


def forget() -> None:
    """Drop every kept value."""
    with _KEPT_LOCK:
        _KEPT.clear()
