"""``mistyle-preview``: stylize a density live in the browser.

    mistyle-preview --density examples/smoke_64.vol                       # the bundled held-out styles
    mistyle-preview --density sim/ --styles paintings/ --look wave.look --port 8100

It serves one page on 127.0.0.1 (``--host`` to listen elsewhere) and prints its URL. The page shows
the styles' thumbnails and takes uploads (the decoder and limits of ``--style``), strength and mix
sliders, a frame slider for sequences, orbit by dragging and zoom by scrolling: the fast layer's
image while you interact, refining into a progressive path-traced image when the view is still.
At full strength the page then fits, in the background, the look that *Render final output* fits
(with ``--render-options``' settings) and switches to it, so that it shows what that render writes;
a change of style cancels the fit. *Render final output* and *Save look* run ``mistyle-render`` for
the current settings and write under ``--out``. Only the page it serves can drive it: other sites'
pages are refused (``server`` says how). ``session`` holds what is shown; ``server`` the web side and
why it is built so.
"""

from __future__ import annotations

import argparse
import signal
import socket
import sys
import threading
from pathlib import Path

from ..conventions import UP_AXES


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="mistyle-preview", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument(
        "--density", type=Path, required=True, help=".vol, .vdb, .npy or .npz density, or a folder of frames"
    )
    p.add_argument("--grid", default=None, help="the float grid of .vdb densities (default: 'density')")
    p.add_argument("--up", choices=UP_AXES, default=None, help="the up axis of .vdb densities (see mistyle-render)")
    p.add_argument(
        "--styles", type=Path, default=None, help="a folder of style pictures (default: the bundled held-out styles)"
    )
    p.add_argument("--look", type=Path, default=None, help="a look file (mistyle-render --save-look) to start with")
    p.add_argument("--host", default="127.0.0.1", help="the address to listen on (default: this machine only)")
    p.add_argument("--port", type=int, default=8090, help="the port (0: any free one)")
    p.add_argument("--res", type=int, default=256, help="the preview's image side in pixels")
    p.add_argument("--out", type=Path, default=Path("out/preview"), help="where the page's renders and looks go")
    p.add_argument("--checkpoint", type=Path, default=None, help="SKPN checkpoint (default: the bundled one)")
    p.add_argument(
        "--render-options",
        default="",
        help='more mistyle-render options for the page\'s final renders and looks, e.g. "--res 1024 --spp 256"',
    )
    return p


def default_styles_folder() -> Path:
    from importlib import resources

    return Path(str(resources.files("mistyle.data").joinpath("heldout_styles")))


def load(args) -> tuple:
    """The session, the style files and the ``job.OutputSpec`` of the page's runs (their settings are the
    session pipeline's), from the command line; ``ValueError`` for bad input."""
    from ..files import load_density_frames, load_style
    from ..look import Look
    from ..outputs import style_files
    from ..pipeline import Pipeline
    from ..stylizer import checked_frames
    from .session import PreviewSession, StyleOption, thumbnail_jpeg

    if not 64 <= args.res <= 1024:
        raise ValueError(f"--res takes 64 to 1024 pixels, got {args.res}.")
    if not 0 <= args.port <= 65535:
        raise ValueError(f"--port takes 0 to 65535, got {args.port}.")
    paths = style_files(args.styles if args.styles is not None else default_styles_folder())
    settings, spec = page_settings(args, paths[0])
    pipeline = Pipeline(settings)
    loaded = load_density_frames(args.density, grid=args.grid, up=args.up)
    frames, _ = checked_frames(loaded.densities, loaded.names)
    styles = []
    for path in paths:
        image = load_style(path)
        styles.append(StyleOption(path.name, image, thumbnail_jpeg(image)))
    look = Look.load(args.look, pipeline.stylizer) if args.look is not None else None
    session = PreviewSession(pipeline, frames, styles, look=look, res=args.res, velocities=loaded.velocities)
    return session, list(paths), spec


def page_settings(args, style: Path) -> tuple:
    """``(pipeline.PipelineSettings, job.OutputSpec)`` of the page's final renders and looks: ``--render-options``
    split as a shell would, parsed and checked as ``mistyle-render`` checks its options (around the preview's
    density, ``--out`` and ``style``, a style it shows), with the preview's ``--checkpoint``, ``--grid`` and
    ``--up``, so that a run reads the density and the network the page shows; ``ValueError`` for a bad one."""
    import shlex

    from ..render_final import output_spec, settings_from, shared_options

    try:
        options = shlex.split(args.render_options)
    except ValueError as error:
        raise ValueError(f"--render-options cannot be split: {error}.") from None
    own = "mistyle-preview's own option or the page's choice: give it to mistyle-preview, not in --render-options"
    parsed = shared_options(options, "--render-options", own, density=args.density, out=args.out, style=style)
    for name in ("checkpoint", "grid", "up"):
        value = getattr(args, name)
        if value is None:
            continue
        if getattr(parsed, name) is not None:
            raise ValueError(f"--{name} is given to mistyle-preview and in --render-options; give it once.")
        setattr(parsed, name, value)
    return settings_from(parsed), output_spec(parsed)


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(joined_render_options(sys.argv[1:] if argv is None else argv))
    try:
        from aiohttp import web

        from .server import build_app

        session, style_paths, spec = load(args)
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            listener.bind((args.host, args.port))
        except OSError as error:
            raise ValueError(
                f"Cannot listen on {args.host}:{args.port} ({error.strerror}); choose another --port (0: any free one)."
            ) from None
        app = build_app(
            session,
            style_paths=style_paths,
            density=args.density,
            out=args.out,
            look=args.look,
            spec=spec,
            host=args.host,
        )
        port = listener.getsockname()[1]
        print(f"mistyle preview: http://{args.host}:{port}/  (Ctrl-C to stop)", flush=True)
        received = serve(lambda: web.run_app(app, sock=listener, print=None, handle_signals=False))
    except ValueError as error:
        print(f"mistyle-preview: error: {error}", file=sys.stderr)
        return 2
    if received is None:
        return 0
    from ..stops import INTERRUPTED_CODE, TERMINATED_CODE, stopped

    word, code = ("terminated", TERMINATED_CODE) if received == signal.SIGTERM else ("interrupted", INTERRUPTED_CODE)
    kept = "the preview server stopped; the outputs its render jobs finished are kept"
    return stopped(f"mistyle-preview: {word}: {kept}", code, in_process=argv is not None)


def joined_render_options(argv: list[str]) -> list[str]:
    """``argv`` with ``--render-options VALUE`` as ``--render-options=VALUE``: argparse takes a value that
    starts with a dash (``--render-options "--vdb"``) for an option of its own and refuses it."""
    joined, items = [], iter(argv)
    for item in items:
        if item == "--render-options":
            value = next(items, None)
            joined.append(item if value is None else f"{item}={value}")
        else:
            joined.append(item)
    return joined


def serve(run) -> int | None:
    """``run()`` (the server, until it is stopped); the signal that stopped it (SIGINT or SIGTERM), or
    None. Either signal stops the server as Ctrl-C does: ``aiohttp.web.run_app`` closes its connections
    and cleans up on the ``KeyboardInterrupt`` raised here."""
    received = []

    def on_signal(number, frame):
        received.append(number)
        raise KeyboardInterrupt

    previous = {}
    if threading.current_thread() is threading.main_thread():  # Ctrl-C only where it is not ignored
        previous[signal.SIGTERM] = signal.signal(signal.SIGTERM, on_signal)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            previous[signal.SIGINT] = signal.signal(signal.SIGINT, on_signal)
    try:
        run()
    except KeyboardInterrupt:
        received.append(signal.SIGINT)
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
    return received[0] if received else None
