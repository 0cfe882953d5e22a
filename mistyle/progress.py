"""Progress bars and status lines for every long stage (training, data generation, refinement,
path tracing), with rates and time estimates from ``tqdm``.

Bars are drawn only on a terminal: when stderr is a pipe or a file (CI, ``nohup``, a log) they are
off, so logs hold the plain status lines alone. ``set_quiet(True)`` (the ``--quiet`` flags) turns
off both bars and status lines; errors are always printed. ``MISTYLE_PROGRESS=lines`` in the
environment draws the bars on a pipe too, as plain ASCII lines at most once a second: what a program
that runs mistyle (the Blender add-on) reads to show progress.
"""

from __future__ import annotations

import os
import sys

from tqdm import tqdm

PROGRESS_ENV = "MISTYLE_PROGRESS"

_quiet = False


def set_quiet(quiet: bool) -> None:
    global _quiet
    _quiet = bool(quiet)


def is_quiet() -> bool:
    return _quiet


def status(message: str) -> None:
    """One status line on stderr, above any bar (nothing when quiet)."""
    if not _quiet:
        tqdm.write(message, file=sys.stderr)


def bar(total: int, description: str, unit: str = "step", initial: int = 0) -> tqdm:
    """A progress bar on stderr; use as a context manager and ``.update(1)`` per unit done
    (``bar.disable`` is true where it is not drawn)."""
    common = dict(total=total, desc=description, unit=unit, initial=initial, file=sys.stderr)
    if os.environ.get(PROGRESS_ENV) == "lines":
        return tqdm(**common, ncols=80, ascii=True, mininterval=1.0, disable=_quiet)
    return tqdm(**common, dynamic_ncols=True, leave=False, disable=True if _quiet else None)  # None: on a terminal


def fit_progress(progress_bar: tqdm):
    """A ``progress(step, steps, loss)`` callback (``look.fit_look``'s) that advances ``progress_bar``
    and shows the loss; ``steps`` sets the bar's total, which a fit may change (coarse steps)."""

    def progress(step: int, steps: int, loss: float) -> None:
        progress_bar.total = steps
        progress_bar.set_postfix_str(f"loss {loss:.4g}", refresh=False)
        progress_bar.update(1)

    return progress
