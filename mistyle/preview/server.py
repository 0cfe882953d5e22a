"""The preview's web server: one page, one websocket, a worker thread that renders.

Why this stack (aiohttp, a websocket, a canvas): what matters is latency and a stream of frames, not
widgets. The browser sends the controls as small JSON messages whenever they change (a drag sends
one per animation frame); the worker renders only the newest state, so a slow frame never queues
more; each image goes back as one binary websocket message (a JPEG behind an 8-byte header) that the
page draws as soon as it is decoded. aiohttp serves the page and the socket from one dependency with
no build step. viser (nerfstudio's viewer) was the other candidate: its camera and widgets come for
free, but its frames go through a three.js background image whose arrival the page cannot count or
pace, and its widgets are not a page a test can drive by role and label.

Routes: ``/`` (the page), ``/thumb/<n>.jpg`` (the n-th style's thumbnail; styles are addressed by
index only, so nothing outside what the server was given can be served), ``/upload`` (a picture,
through ``session.decode_upload``), ``/job/final`` and ``/job/look`` (``mistyle-render`` runs for the
current controls, written under ``--out``; a saved look becomes the session's), ``/ws`` (controls in,
frames and status out).

Frames: header ``kind (1 byte: 0 fast layer, 1 path traced) | 3 bytes 0 | samples (uint32, little
endian)`` then the JPEG.
"""

from __future__ import annotations

import asyncio
import json
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import replace
from importlib import resources
from pathlib import Path

from .session import Camera, Controls, PreviewSession, jpeg

IDLE_BEFORE_PATH_TRACING_S = 0.35
FAST, PATH_TRACED = 0, 1


def safe_name(name: str) -> str:
    """``name`` with anything but letters, digits, ``_``, ``.`` and ``-`` replaced: a file name of the server's."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


def frame_message(kind: int, samples: int, image) -> bytes:
    return struct.pack("<B3xI", kind, samples) + jpeg(image)


class Worker(threading.Thread):
    """Renders the newest controls: the fast layer's image whenever they change, then path-traced
    passes while they stay still. The only thread that touches Mitsuba and torch."""

    def __init__(self, session: PreviewSession, send):
        super().__init__(daemon=True, name="mistyle-preview-render")
        self.session = session
        self.send = send  # (bytes | dict) -> None, thread-safe
        self.controls = session.initial_controls()
        self.version = 1  # bumped by every change
        self.changed = threading.Condition()
        self.running = True

    def update(self, controls: Controls) -> None:
        with self.changed:
            self.controls = controls
            self.version += 1
            self.changed.notify()

    def stop(self) -> None:
        with self.changed:
            self.running = False
            self.changed.notify()

    def run(self) -> None:
        shown = 0
        while True:
            with self.changed:
                while self.running and self.version == shown:
                    self.changed.wait()
                if not self.running:
                    return
                controls, shown = self.controls, self.version
            try:
                self.render(controls, shown)
            except Exception as error:  # a bad state must not end the preview; the page shows why
                self.send({"type": "error", "message": f"{type(error).__name__}: {error}"})

    def render(self, controls: Controls, version: int) -> None:
        session = self.session
        stylized = session.stylized
        image = session.layer_image(controls)
        self.send(frame_message(FAST, 0, image))
        status = {"type": "status", "layer_ms": round(1000 * session.timings["layer_seconds"], 1)}
        if session.stylized != stylized:
            status["stylize_ms"] = round(1000 * session.timings["stylize_seconds"], 1)
        self.send(status)
        quiet_since = time.monotonic()
        while time.monotonic() - quiet_since < IDLE_BEFORE_PATH_TRACING_S:
            if self.version != version:
                return
            time.sleep(0.02)
        for image, samples in session.path_traced_passes(controls):
            if self.version != version or not self.running:
                return
            self.send(frame_message(PATH_TRACED, samples, image))


class Jobs:
    """``mistyle-render`` runs started from the page (final output, a look), one at a time."""

    def __init__(self, out: Path, density: Path, look: Path | None, options: list[str]):
        self.out, self.density, self.look, self.options = out, density, look, options
        self.process: subprocess.Popen | None = None

    def start(self, kind: str, controls: Controls, session: PreviewSession, style_paths: list[Path]) -> Path:
        if self.process is not None and self.process.poll() is None:
            raise ValueError("A render started from the preview is still running; wait for it to finish.")
        command = [sys.executable, "-m", "mistyle.render_final", "--density", str(self.density), "--quiet"]
        if controls.look:
            name = f"look_{self.look.stem}"
            command += ["--look", str(self.look)]
        else:
            name = safe_name(Path(style_paths[controls.style].name).stem)
            command += session.style_arguments(controls, style_paths)
        if kind == "look":
            if controls.look:
                raise ValueError("This is a look already; pick a style to fit a new one.")
            target = self.out / f"{name}.look"
            command += ["--save-look", str(target)]
        else:
            target = self.out / name
            command += ["--out", str(target), "--overwrite"]
        command += self.options
        self.out.mkdir(parents=True, exist_ok=True)
        self.process = subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, text=True
        )
        return target


def build_app(
    session: PreviewSession,
    *,
    style_paths: list[Path],
    density: Path,
    out: Path,
    look: Path | None,
    render_options: list[str] = (),
):
    """The aiohttp application of the preview (module docstring). ``render_options``: more
    ``mistyle-render`` options for the page's jobs."""
    from aiohttp import WSMsgType, web

    sockets: set = set()
    loop_holder: dict = {}
    uploads = Path(tempfile.mkdtemp(prefix="mistyle-preview-styles-"))
    jobs = Jobs(out, density, look, list(render_options))

    def send(message) -> None:
        """From the worker thread: to every open page, waiting until sent (so frames never pile up)."""
        loop = loop_holder.get("loop")
        if loop is None:
            return
        for socket in list(sockets):
            coroutine = socket.send_bytes(message) if isinstance(message, bytes) else socket.send_json(message)
            try:
                asyncio.run_coroutine_threadsafe(coroutine, loop).result(timeout=5)
            except Exception:  # a closed page: its handler removes it
                pass

    worker = Worker(session, send)

    def state() -> dict:
        controls = worker.controls
        return {
            "type": "state",
            "styles": [style.name for style in session.styles],
            "frames": len(session.frames),
            "look": session.look is not None,
            "controls": {
                "style": controls.style,
                "mix_with": controls.mix_with,
                "mix": controls.mix,
                "strength": controls.strength,
                "frame": controls.frame,
                "look": controls.look,
                "camera": [controls.camera.azimuth, controls.camera.elevation, controls.camera.distance],
            },
        }

    async def page(request):
        text = resources.files("mistyle.preview").joinpath("page.html").read_text()
        return web.Response(text=text, content_type="text/html")

    async def thumbnail(request):
        index = int(request.match_info["index"])
        if not 0 <= index < len(session.styles):
            raise web.HTTPNotFound()
        return web.Response(body=session.styles[index].thumbnail, content_type="image/jpeg")

    async def upload(request):
        from .session import decode_upload

        try:
            reader = await request.multipart()
            part = await reader.next()
            if part is None or part.name != "style":
                raise ValueError("The upload holds no picture (a form field named 'style').")
            name = part.filename or "upload.png"
            data = await part.read(decode=False)
            style = await asyncio.get_running_loop().run_in_executor(None, decode_upload, name, bytes(data))
        except ValueError as error:
            return web.json_response({"error": str(error)}, status=400)
        except Exception as error:  # a malformed request: the page says so, the server goes on
            return web.json_response({"error": f"The upload could not be read ({error})."}, status=400)
        index = len(session.styles)
        path = uploads / f"{index:03d}_{safe_name(style.name)}"
        path.write_bytes(bytes(data))
        style_paths.append(path)
        session.styles.append(style)
        worker.update(replace(worker.controls, style=index, look=False))
        for socket in list(sockets):
            await socket.send_json(state())
        return web.json_response({"index": index, "name": style.name})

    async def job(request):
        kind = request.match_info["kind"]
        try:
            target = jobs.start(kind, worker.controls, session, style_paths)
        except ValueError as error:
            return web.json_response({"error": str(error)}, status=409)

        async def watch():
            process = jobs.process
            output = await asyncio.get_running_loop().run_in_executor(None, process.communicate)
            lines = [line for line in (output[0] or "").splitlines() if line.strip()]
            if process.returncode == 0:
                message = {"type": "job", "kind": kind, "done": True, "path": str(target)}
                if kind == "look":  # the page can apply the look it just saved
                    from ..look import Look

                    session.look = Look.load(target, session.stylizer)
                    jobs.look = target
                    for socket in list(sockets):
                        await socket.send_json(state())
            else:
                message = {"type": "job", "kind": kind, "error": lines[-1] if lines else "mistyle-render failed"}
            for socket in list(sockets):
                await socket.send_json(message)

        asyncio.get_running_loop().create_task(watch())
        return web.json_response({"started": kind, "path": str(target)})

    async def websocket(request):
        socket = web.WebSocketResponse(max_msg_size=1 << 20)
        await socket.prepare(request)
        sockets.add(socket)
        await socket.send_json(state())
        worker.update(worker.controls)  # a first image for the new page
        try:
            async for message in socket:
                if message.type != WSMsgType.TEXT:
                    continue
                try:
                    fields = json.loads(message.data)
                    worker.update(session.checked(controls_from(worker.controls, fields)))
                except (ValueError, TypeError, KeyError) as error:
                    await socket.send_json({"type": "error", "message": f"bad control message: {error}"})
        finally:
            sockets.discard(socket)
        return socket

    async def started(app):
        loop_holder["loop"] = asyncio.get_running_loop()
        worker.start()

    async def stopped(app):
        worker.stop()
        # A daemon thread killed inside Mitsuba at exit aborts the process: let it finish its pass.
        await asyncio.get_running_loop().run_in_executor(None, worker.join, 60)
        shutil.rmtree(uploads, ignore_errors=True)

    app = web.Application(client_max_size=80 * 1024 * 1024)
    app.router.add_get("/", page)
    app.router.add_get(r"/thumb/{index:\d+}.jpg", thumbnail)
    app.router.add_post("/upload", upload)
    app.router.add_post(r"/job/{kind:final|look}", job)
    app.router.add_get("/ws", websocket)
    app.on_startup.append(started)
    app.on_cleanup.append(stopped)
    return app


def controls_from(current: Controls, fields: dict) -> Controls:
    """``current`` with the fields a page sent (``style``, ``mix_with``, ``mix``, ``strength``, ``frame``,
    ``look``, ``camera``: ``[azimuth, elevation, distance]``)."""
    changes = {}
    for name, kind in (("style", int), ("mix", float), ("strength", float), ("frame", int), ("look", bool)):
        if name in fields:
            changes[name] = kind(fields[name])
    if "mix_with" in fields:
        changes["mix_with"] = None if fields["mix_with"] is None else int(fields["mix_with"])
    if "camera" in fields:
        azimuth, elevation, distance = (float(value) for value in fields["camera"])
        changes["camera"] = Camera(azimuth, elevation, distance)
    return replace(current, **changes)
