"""A sequence rendered from one look on a Dask cluster: one task per chunk of frames (``mistyle-farm``).

    mistyle-render --density sim/ --style wave.png --save-look wave.look        # once, on one machine
    mistyle-farm --scheduler tcp://head:8786 --density sim/ --look wave.look --out shots/wave --chunk 10 \
        -- --res 512 --spp 128                                                  # every frame, many machines
    mistyle-farm --local-workers 2 --density sim/ --look wave.look --out shots/wave   # this machine's cores

The look file is read once here and shipped to every worker with the tasks (``Client.scatter``), so
workers need only mistyle, the density frames and the output folder on a shared file system (and a
``--checkpoint`` there, if the look was not fitted with the bundled network). Each task is
``mistyle-render --look ... --frames A-B`` (``render_chunk``): its frames are stylized from the look
alone and path traced with per-frame seeds, and it merges them into ``--out`` under the folder's lock,
so the folder equals one process's render bit for bit whatever the chunks and their order
(``tests/test_farm.py``). A failed chunk is reported with its frames; rerun just those with ``--frames``.

Dask rather than Ray: the work is a flat list of independent, coarse tasks with nothing to share but
one small file, which Dask's ``distributed`` runs from a pure-Python install (a scheduler and workers
started with ``dask scheduler`` / ``dask worker ADDRESS``, or a ``LocalCluster`` in one command, as the
tests do), with no daemon or object store to deploy. A render farm (Deadline, OpenCue) needs neither:
give each of its tasks one ``mistyle-render --look ... --frames A-B`` command (docs/looks.md).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

DEFAULT_CHUNK = 8
"""Frames per task: enough to amortise loading the network (about a second) against a frame's render."""


def frame_chunks(count: int, size: int, frames: tuple[int, int] | None = None) -> list[tuple[int, int]]:
    """Inclusive ``(first, last)`` ranges of at most ``size`` frames covering ``frames`` (default all ``count``)."""
    if size < 1:
        raise ValueError(f"--chunk must be at least 1 frame, got {size}.")
    first, last = (0, count - 1) if frames is None else frames
    if not 0 <= first <= last < count:
        raise ValueError(f"--frames {first}-{last} lies outside the sequence's frames 0-{count - 1}.")
    return [(start, min(start + size - 1, last)) for start in range(first, last + 1, size)]


def render_chunk(look: bytes, density: str, out: str, first: int, last: int, options: list[str]) -> dict:
    """On a worker: ``mistyle-render --density density --look <look> --out out --frames first-last options``.
    Returns ``{"frames": [first, last]}``; raises ``RuntimeError`` with the command's message if it fails."""
    import contextlib
    import io

    from .render_final import main

    with tempfile.TemporaryDirectory(prefix="mistyle-look-") as folder:
        path = Path(folder) / "shipped.look"
        path.write_bytes(look)
        errors = io.StringIO()
        argv = ["--density", density, "--look", str(path), "--out", out, "--frames", f"{first}-{last}", "--quiet"]
        with contextlib.redirect_stderr(errors):
            code = main(argv + list(options))
    if code != 0:
        raise RuntimeError(f"frames {first}-{last}: {errors.getvalue().strip() or f'exit status {code}'}")
    return {"frames": [first, last]}


def render_on_cluster(
    client,
    density,
    look,
    out,
    *,
    chunk: int = DEFAULT_CHUNK,
    frames: tuple[int, int] | None = None,
    options: list[str] | None = None,
) -> list[dict]:
    """Render every frame (or ``frames``) of ``density`` from the look file ``look`` into ``out`` on the Dask
    ``client``'s workers, ``chunk`` frames a task; ``options``: further ``mistyle-render`` options."""
    from .io import density_frame_files

    count = len(density_frame_files(density))
    ranges = frame_chunks(count, chunk, frames)
    look_bytes = Path(look).read_bytes()
    shipped = client.scatter(look_bytes, broadcast=True)
    density, out = str(Path(density).resolve()), str(Path(out).resolve())
    tasks = [
        client.submit(render_chunk, shipped, density, out, first, last, list(options or []), pure=False)
        for first, last in ranges
    ]
    return client.gather(tasks)


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="mistyle-farm", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--scheduler", help="a Dask scheduler's address, e.g. tcp://head:8786")
    where.add_argument("--local-workers", type=int, help="start a local cluster of this many worker processes")
    p.add_argument("--density", type=Path, required=True, help="a folder of density frames (or one file)")
    p.add_argument("--look", type=Path, required=True, help="a look written by mistyle-render --save-look")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--chunk", type=int, default=DEFAULT_CHUNK, help="frames per task")
    p.add_argument("--frames", default=None, metavar="A-B", help="only these frames (0-based, inclusive)")
    p.add_argument("options", nargs=argparse.REMAINDER, help="after --: options passed to every mistyle-render")
    return p


def main(argv=None) -> int:
    from .stops import run_stoppable

    args = parser().parse_args(argv)
    try:
        kept = f"the frames finished so far are kept in {args.out}"
        return run_stoppable(lambda: _farm(args), kept, in_process=argv is not None)
    except (ValueError, OSError, RuntimeError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2


def _farm(args) -> int:
    """The command's work: the checks, the cluster, the chunks; the cluster is closed however it ends."""
    from .look import Look
    from .render_final import parse_frame_range

    options = args.options[1:] if args.options[:1] == ["--"] else args.options
    if not args.look.is_file():
        raise ValueError(f"Look {args.look} does not exist; fit one with mistyle-render --save-look.")
    if not args.density.exists():
        raise ValueError(f"Density {args.density} does not exist.")
    if args.local_workers is not None and not 1 <= args.local_workers <= 256:
        raise ValueError(f"--local-workers must lie in [1, 256], got {args.local_workers}.")
    named = options[options.index("--checkpoint") + 1] if "--checkpoint" in options[:-1] else None
    Look.load(args.look, checkpoint=named)  # a damaged look or another network: one line here, not per task
    frames = None if args.frames is None else parse_frame_range(args.frames)
    from distributed import Client, LocalCluster

    if args.local_workers is not None:
        cluster = LocalCluster(n_workers=args.local_workers, threads_per_worker=1, processes=True)
        client = Client(cluster)
    else:
        cluster, client = None, Client(args.scheduler, timeout=30)
    try:
        done = render_on_cluster(
            client, args.density, args.look, args.out, chunk=args.chunk, frames=frames, options=options
        )
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    print(f"wrote {args.out}/: {sum(b - a + 1 for a, b in (d['frames'] for d in done))} frames in {len(done)} chunks")
    return 0


if __name__ == "__main__":
    sys.exit(main())
