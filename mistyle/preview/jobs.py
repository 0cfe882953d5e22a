"""The runs the page starts (*Render final output*, *Save look*): ``job.render_outputs`` in a process of its
own, one at a time."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from .checks import safe_name
from .session import Controls, PreviewSession


def render_in_process(settings, spec, request, errors) -> None:
    """A run the page started, in a process of its own (``Jobs``): ``job.render_outputs`` with nothing on the
    terminal; its one-line error, if any, goes to ``errors`` (a ``multiprocessing`` connection)."""
    import contextlib
    import io

    from ..backend import BackendError
    from ..job import render_outputs
    from ..progress import set_quiet
    from ..stops import run_stoppable

    def work() -> int:
        render_outputs(settings, spec, request)
        return 0

    set_quiet(True)
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            code = run_stoppable(work, "the output being written was removed", in_process=True)
        message = None if code == 0 else "stopped"
    except (ValueError, OSError, BackendError) as error:
        message = str(error).splitlines()[0] if str(error) else type(error).__name__
    except Exception as error:  # never a traceback on the server's terminal: the page shows the line
        message = f"unexpected {type(error).__name__}: {str(error).splitlines()[0] if str(error) else ''}"
    errors.send(message)
    errors.close()


class Jobs:
    """Runs started from the page (a final output, a look), one at a time, each in a process of its own
    (``render_in_process``) so that the page stays live: ``job.render_outputs`` with the page's controls
    and the settings of ``--render-options``, as ``mistyle-render`` would make them."""

    def __init__(self, out: Path, density: Path, look: Path | None, settings, spec):
        from ..job import OutputSpec

        self.out, self.density, self.look, self.settings = out, density, look, settings
        self.spec = OutputSpec() if spec is None else spec
        self.process = None
        self.errors = None

    def running(self) -> bool:
        return self.process is not None and self.process.is_alive()

    def start(self, kind: str, controls: Controls, session: PreviewSession, style_paths: list[Path]) -> Path:
        import multiprocessing

        from ..job import RenderRequest

        if self.running():
            raise ValueError("A render started from the preview is still running; wait for it to finish.")
        settings = replace(self.settings, strength=controls.strength)
        if controls.look:
            name, style = f"look_{self.look.stem}", {"look": self.look}
        else:
            name = safe_name(Path(style_paths[controls.style].name).stem)
            style = session.style_request(controls, style_paths)
        if kind == "look":
            if controls.look:
                raise ValueError("This is a look already; pick a style to fit a new one.")
            if controls.strength < 1.0:
                raise ValueError("A look holds its style at full strength; set the strength to 1 to save one.")
            target = self.out / f"{name}.look"
            request = RenderRequest(density=(self.density,), save_look=target, **style)
        else:
            target = self.out / name
            request = RenderRequest(density=(self.density,), out=target, overwrite=True, **style)
        self.out.mkdir(parents=True, exist_ok=True)
        context = multiprocessing.get_context("spawn")  # a fresh interpreter: no copy of the server's threads
        self.errors, sent = context.Pipe(duplex=False)
        self.process = context.Process(target=render_in_process, args=(settings, self.spec, request, sent))
        self.process.start()
        sent.close()
        return target

    def wait(self) -> str | None:
        """Until the run ends: None if it wrote its files, else its one-line error."""
        self.process.join()
        try:
            message = self.errors.recv() if self.errors.poll() else "the render's process ended without a word"
        except EOFError:
            message = f"the render's process ended with code {self.process.exitcode}"
        return message
