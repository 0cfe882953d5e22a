"""A sequence rendered from one look on a Dask cluster: one task per chunk of frames (``mistyle-farm``).

    mistyle-render --density sim/ --style wave.png --save-look wave.look        # once, on one machine
    mistyle-farm --scheduler tcp://head:8786 --density sim/ --look wave.look --out shots/wave --chunk 10 \
        -- --res 512 --spp 128                                                  # every frame, many machines
    mistyle-farm --local-workers 2 --density sim/ --look wave.look --out shots/wave   # this machine's cores

The look file is read once here and shipped to every worker with the tasks (``Client.scatter``), so
workers need only mistyle, the density frames and the output folder on a shared file system (and a
``--checkpoint`` there, if the look was not fitted with the bundled network). Each task does what
``mistyle-render --look ... --frames A-B`` does (``render_chunk``, through ``job.render_look_chunk``,
with the settings parsed once here; a worker keeps its network loaded from one chunk to the next): its
frames are stylized from the look alone and path traced with per-frame seeds, and it merges them into
``--out`` under the folder's lock, so the folder equals one process's render bit for bit whatever the
chunks and their order (``tests/test_look.py``). A failed chunk is reported with its frames; rerun just
those with ``--frames``.

Everything a worker would refuse is checked here before the cluster starts: the options after ``--``
(parsed and checked as ``mistyle-render`` does; ``--out``, ``--frames``, ``--density`` and ``--look``
are the farm's own), the look, the frames and ``--out`` (``mistyle.ownership``: never a file, nor a
folder holding files mistyle did not write). Each task keeps its copy of the look in a staging folder
beside ``--out`` named after its worker process, and a local cluster's scratch space is the farm's own
such folder, so whatever a killed run leaves there is removed by the next run into that ``--out``.
Ctrl-C stops a local cluster's workers at once (they run in their own process group, so the terminal's
signal reaches only this process, which kills them) and removes their unfinished chunks.

Dask rather than Ray: the work is a flat list of independent, coarse tasks with nothing to share but
one small file, which Dask's ``distributed`` runs from a pure-Python install (a scheduler and workers
started with ``dask scheduler`` / ``dask worker ADDRESS``, or a ``LocalCluster`` in one command, as the
tests do), with no daemon or object store to deploy. A render farm (Deadline, OpenCue) needs neither:
give each of its tasks one ``mistyle-render --look ... --frames A-B`` command (docs/looks.md).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .files.paths import one_line, os_error_line

DEFAULT_CHUNK = 8
"""Frames per task: enough to amortise loading the network (about a second) against a frame's render."""
POLL_SECONDS = 0.2


def frame_chunks(count: int, size: int, frames: tuple[int, int] | None = None) -> list[tuple[int, int]]:
    """Inclusive ``(first, last)`` ranges of at most ``size`` frames covering ``frames`` (default all ``count``)."""
    if size < 1:
        raise ValueError(f"--chunk must be at least 1 frame, got {size}.")
    first, last = (0, count - 1) if frames is None else frames
    if not 0 <= first <= last < count:
        raise ValueError(f"--frames {first}-{last} lies outside the sequence's frames 0-{count - 1}.")
    return [(start, min(start + size - 1, last)) for start in range(first, last + 1, size)]


def chunk_settings(options: list[str], density=Path("density"), look=Path("look"), out=Path("out")) -> tuple:
    """``(pipeline.PipelineSettings, job.OutputSpec)`` of every chunk, from the ``mistyle-render`` options
    after ``--``, parsed and checked as that command does (``render_final.shared_options``)."""
    from .render_final import output_spec, settings_from, shared_options

    own = "mistyle-farm's own option: give it before --, not after it (mistyle-farm ... --NAME VALUE -- OTHERS)"
    parsed = shared_options(options, "after --", own, density=density, out=out, look=look)
    return settings_from(parsed), output_spec(parsed)


_WORKER_PIPELINES: dict = {}
"""A worker process's pipelines by their settings: its network stays loaded from one chunk to the next."""


def worker_pipeline(settings):
    """The ``pipeline.Pipeline`` of ``settings`` in this process, made on its first chunk."""
    from .backend import use_variant
    from .pipeline import Pipeline

    key = repr(settings)
    if key not in _WORKER_PIPELINES:
        use_variant(settings.device)
        _WORKER_PIPELINES.clear()  # one network at a time in a worker's memory
        _WORKER_PIPELINES[key] = Pipeline(settings)
    return _WORKER_PIPELINES[key]


def render_chunk(look: bytes, density: str, out: str, first: int, last: int, settings, spec) -> dict:
    """On a worker: frames ``first``-``last`` of ``density`` from the look (its file's bytes), with the
    ``pipeline.PipelineSettings`` and ``job.OutputSpec`` that ``chunk_settings`` made of the options,
    merged into ``out`` (``job.render_look_chunk``, as ``mistyle-render --look ... --frames A-B``).
    Returns ``{"frames": [first, last]}``, with ``"error"`` (one line) if it failed: a task that returns
    its failure keeps Dask from logging it as a crash on the worker."""
    import contextlib
    import io

    from .backend import BackendError
    from .job import render_look_chunk
    from .ownership import chunk_staging
    from .progress import set_quiet

    set_quiet(True)
    # The look lies in a staging folder beside the output, named after this worker process: removed
    # after the chunk, or by the next run once the process is gone (``ownership.remove_dead_staging``).
    try:
        with chunk_staging(Path(out)) as folder, contextlib.redirect_stdout(io.StringIO()):
            path = folder / "shipped.look"
            path.write_bytes(look)
            render_look_chunk(worker_pipeline(settings), spec, density, path, out, (first, last))
    except (ValueError, OSError, BackendError) as error:
        return {"frames": [first, last], "error": str(error).splitlines()[0] if str(error) else type(error).__name__}
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
    ``client``'s workers, ``chunk`` frames a task; ``options``: further ``mistyle-render`` options.
    ``RuntimeError`` naming the failed chunks once every chunk has ended."""
    import time

    from .files import density_frame_files
    from .stops import raise_if_requested

    ranges = frame_chunks(len(density_frame_files(density)), chunk, frames)
    settings = chunk_settings(list(options or []), density, look, out)
    shipped = client.scatter(Path(look).read_bytes(), broadcast=True)
    density, out = str(Path(density).resolve()), str(Path(out).resolve())
    tasks = [
        client.submit(render_chunk, shipped, density, out, first, last, *settings, pure=False) for first, last in ranges
    ]
    # Polled rather than gathered: Ctrl-C then finds no gather of Dask's half way, to be cancelled noisily.
    while not all(task.done() for task in tasks):
        raise_if_requested()
        time.sleep(POLL_SECONDS)
    done, failed = [], []
    for (first, last), task in zip(ranges, tasks):
        try:
            result = task.result()
        except Exception as error:  # the worker died, or the task raised: one line all the same
            result = {"frames": [first, last], "error": f"{type(error).__name__}: {error}".splitlines()[0]}
        (failed if "error" in result else done).append(result)
    if failed:
        which = ", ".join(f"{a}-{b}" for a, b in (r["frames"] for r in failed))
        (a, b), message = failed[0]["frames"], failed[0]["error"].removeprefix("error: ")
        raise RuntimeError(
            f"{len(failed)} of {len(ranges)} chunks failed (frames {which}; once fixed, rerun them with --frames); "
            f"frames {a}-{b}: {message}"
        )
    return done


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
    p.add_argument(
        "options",
        nargs=argparse.REMAINDER,
        help="after --: options passed to every mistyle-render (not --out, --frames, --density, --look: the farm's)",
    )
    return p


def main(argv=None) -> int:
    from .stops import run_stoppable

    args = parser().parse_args(argv)
    try:
        kept = f"the frames finished so far are kept in {args.out}"
        return run_stoppable(lambda: _farm(args), kept, in_process=argv is not None)
    except OSError as error:
        print(f"error: {os_error_line(error, 'choose a writable --out')}", file=sys.stderr)
        return 2
    except (ValueError, RuntimeError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2


def check_out(out: Path, density: Path, look: Path) -> None:
    """``--out`` as every chunk will find it: a folder (or nothing yet) holding only mistyle's files,
    neither an input nor inside one."""
    from .outputs import plan_outputs

    if out.exists() and not out.is_dir():
        raise ValueError(f"The output path {out} is a file; choose a folder for --out.")
    plan_outputs([density], None, [look], None, out, overwrite=True)


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
    frames = None if args.frames is None else parse_frame_range(args.frames)
    check_out(args.out, args.density, args.look)
    settings, _ = chunk_settings(options, args.density, args.look, args.out)
    from .files import density_frame_files

    frame_chunks(len(density_frame_files(args.density)), args.chunk, frames)
    Look.load(args.look, checkpoint=settings.checkpoint)  # a damaged look or another network: one line here
    with _cluster(args) as client:
        done = render_on_cluster(
            client, args.density, args.look, args.out, chunk=args.chunk, frames=frames, options=options
        )
    print(f"wrote {args.out}/: {sum(b - a + 1 for a, b in (d['frames'] for d in done))} frames in {len(done)} chunks")
    return 0


def _prepare_worker() -> int:
    """On a local worker: leave the terminal's process group, so that Ctrl-C reaches the farm's client
    alone (which then kills the workers) rather than each worker half way through a frame; and give
    tqdm a thread lock instead of its default process-shared one, a semaphore that a killed worker
    would leave for the resource tracker to report as leaked. Returns the worker's pid."""
    import os
    import threading

    from tqdm.std import tqdm

    os.setpgrp()
    tqdm.set_lock(threading.RLock())
    return os.getpid()


SCHEDULER_TIMEOUT = 30
"""Seconds ``--scheduler``'s address has to answer before the farm gives up on it."""


class _cluster:
    """``with _cluster(args) as client``: a client of ``--scheduler``, or of a local cluster of
    ``--local-workers``. However the block ends, the client is closed; a local cluster is closed too,
    at once when the block failed or was interrupted (its workers killed), and the staging folders of
    its chunks are removed (``ownership.remove_dead_staging``)."""

    def __init__(self, args):
        self.args, self.cluster, self.client, self.pids, self.scratch = args, None, None, [], None

    def __enter__(self):
        from distributed import Client

        from .ownership import make_staging

        if self.args.scheduler is not None:
            try:
                self.client = Client(self.args.scheduler, timeout=SCHEDULER_TIMEOUT)
            except (OSError, ValueError, TypeError) as error:  # Dask's kinds for a bad or unreachable address
                raise ValueError(
                    f"--scheduler {self.args.scheduler}: no Dask scheduler answered there ({one_line(error)}). Give "
                    "the address `dask scheduler` printed (tcp://HOST:8786), or leave --scheduler out to start "
                    "--local-workers."
                ) from None
            return self.client
        # Dask's scratch space, as a staging folder of this process: removed when it ends, or by the
        # next run once this process is gone.
        out = Path(self.args.out).resolve()
        out.parent.mkdir(parents=True, exist_ok=True)
        self.scratch = make_staging(out, "chunk")
        try:
            self._start_local()
        except BaseException:
            self.__exit__(*sys.exc_info())
            raise
        return self.client

    def _start_local(self) -> None:
        import logging
        import signal

        import dask
        from distributed import Client, LocalCluster

        # The workers must not see the terminal's Ctrl-C: a worker stopped half way leaves its chunk
        # behind, and Mitsuba answers the signal by cutting a render short, a frame the chunk would
        # then merge. They are spawned from the cluster's thread, which inherits this thread's signal
        # mask, and keep it: SIGINT stays blocked there (here a Ctrl-C waits for the cluster to be up).
        # Once up, each leaves the terminal's process group too.
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            # Dask's scratch space (the scheduler's and the workers') in the farm's staging folder.
            with dask.config.set({"temporary-directory": str(self.scratch)}):
                self.cluster = LocalCluster(
                    n_workers=self.args.local_workers,
                    threads_per_worker=1,
                    processes=True,
                    silence_logs=logging.CRITICAL,  # a worker's failure comes back as its chunk's one line
                    dashboard_address=None,
                )
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
        self.client = Client(self.cluster)
        self.pids = list(self.client.run(_prepare_worker).values())

    def __exit__(self, kind, error, trace):
        import contextlib
        import gc
        import logging
        import os
        import shutil
        import signal
        import time

        from .ownership import remove_dead_staging

        if kind is not None:
            # Stopped (Ctrl-C, a failure): the comms this process still has with the workers killed next
            # close half way, which Dask logs as tracebacks; the one line the command prints says it all.
            logging.getLogger("distributed").setLevel(logging.CRITICAL)
        if kind is not None and self.cluster is not None:
            for nanny in self.cluster.workers.values():
                nanny.close_gracefully()  # no restart of the worker killed next
            for pid in self.pids:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
        if self.client is not None:
            with contextlib.suppress(Exception):
                self.client.close(timeout=5)
        if self.cluster is not None:
            with contextlib.suppress(Exception):
                self.cluster.close(timeout=5)
        self.cluster = self.client = None
        if self.scratch is not None:
            gc.collect()  # the closed workers' queues release their semaphores before an interrupt's os._exit
            shutil.rmtree(self.scratch, ignore_errors=True)
            deadline = time.monotonic() + 2  # the cluster has joined its workers; a last look
            while any(_alive(pid) for pid in self.pids) and time.monotonic() < deadline:
                time.sleep(0.05)
            remove_dead_staging(Path(self.args.out).resolve())  # the chunks the stopped workers left
        return False


def _alive(pid: int) -> bool:
    import os

    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    return True


if __name__ == "__main__":
    sys.exit(main())
