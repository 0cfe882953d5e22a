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
through ``session.decode_upload``), ``/job/final`` and ``/job/look`` (runs of ``job.render_outputs``, as
``mistyle-render`` makes them, for the current controls, written under ``--out``; a saved look becomes the
session's), ``/ws`` (controls in, frames and status out).

Frames: header ``kind (1 byte: 0 fast layer, 1 path traced) | 3 bytes 0 | samples (uint32, little
endian)`` then the JPEG. Each fast frame is followed by a ``status`` saying what it shows (``shows``:
``"network"`` or ``"look"``). Where *Render final output* fits a look (``PreviewSession.fits_look``),
the worker fits it after the network's frame and reports ``fit`` messages (``step``/``steps``, then
``done`` with the fit's ``seconds`` and ``first_look_ms``, from the change to the look's first frame).

Who may drive it: only the page this server run served. Listening on loopback is not enough, since any
web page the user opens can send requests to loopback, and DNS rebinding can give another site's
name a loopback address. So every request is checked (``refusal``), and a refused one gets a 403 with
a JSON ``error`` naming what was wrong:

* ``Host`` must name the address the request arrived on, with its port: ``127.0.0.1:PORT``,
  ``localhost:PORT`` or ``[::1]:PORT`` on loopback, else that address or ``--host`` as given. A
  rebinding page's ``Host`` is its own domain name, so it gets nothing, not even the page and its
  token.
* ``Origin``, when present, must be the server's own origin (``http://`` and an allowed ``Host``).
  Browsers send it on every websocket handshake and on every ``fetch`` POST, so a page on another
  site is refused by it alone.
* The websocket, every POST and any route but ``/`` and the thumbnails carry the server run's token
  (``secrets.token_urlsafe``), in the ``X-Mistyle-Token`` header or a ``token`` query parameter (the
  websocket's way: a browser cannot set its headers). The page gets it in its
  ``<meta name="mistyle-token">``, filled in when served with ``Cache-Control: no-store`` (a page
  left open from an earlier run is refused until reloaded) and in no frame of another site
  (``frame-ancestors 'none'``). ``/`` and the thumbnails need no token: another site's page may show
  a thumbnail but never read its pixels, nor read the page.
* A request without ``Origin``, the websocket's included, is not a browser page's (every browser
  sends one on a handshake and on a ``fetch`` POST) but curl's or a script's. It is not refused for
  that alone, since the token is what it must carry: a script gets the token by reading ``/`` as the
  page does, which only a client that reaches the server at its own address can.

Uploads are written to a temporary folder (the page's runs read them by path) removed when the
server stops. A run keeps at most ``MAX_UPLOADS`` of them and ``MAX_UPLOADS_BYTES`` in all; an upload
past either is refused with 413 rather than dropping older ones, since styles are addressed by
index: dropping one would renumber the styles under every open page and its cached images.

Controls arrive as JSON objects and are checked per message (``controls_from``): a message with an
unknown key, a value of the wrong type, a non-finite number or an index past the session's styles or
frames is answered with an ``error`` (and the current ``state``) to its page only, and none of it is
applied; the other pages and the renders go on with the controls as they were.
"""

from __future__ import annotations

import asyncio
import html
import json
import secrets
import struct
import threading
import time
from dataclasses import replace
from importlib import resources
from pathlib import Path

from .checks import MAX_UPLOADS, MAX_UPLOADS_BYTES, Uploads, controls_from, refusal
from .jobs import Jobs
from .session import Controls, PreviewSession, jpeg

IDLE_BEFORE_PATH_TRACING_S = 0.35
FAST, PATH_TRACED = 0, 1
TOKEN_PLACEHOLDER = "{{MISTYLE_TOKEN}}"


def frame_message(kind: int, samples: int, image) -> bytes:
    return struct.pack("<B3xI", kind, samples) + jpeg(image)


class FitCancelled(Exception):
    """Raised into a look's fit by the page's next style change: the fit ends and nothing is kept."""


class Worker(threading.Thread):
    """Renders the newest controls: the fast layer's image whenever they change; where the final render
    fits a look, fits that look (camera and frame changes keep being shown with the network meanwhile,
    a style change cancels it) and shows it; then path-traced passes while the controls stay still.
    The only thread that touches Mitsuba and torch."""

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
            except FitCancelled:
                pass
            except Exception as error:  # a bad state must not end the preview; the page shows why
                self.send({"type": "error", "message": f"{type(error).__name__}: {error}"})

    def show_fast(self, controls: Controls) -> None:
        """The fast layer's image of ``controls`` and a status line saying what it shows."""
        session = self.session
        stylized = session.stylized
        image = session.layer_image(controls)
        self.send(frame_message(FAST, 0, image))
        status = {
            "type": "status",
            "layer_ms": round(1000 * session.timings["layer_seconds"], 1),
            "shows": "look" if session.shown_look(controls) is not None else "network",
        }
        if session.stylized != stylized:
            status["stylize_ms"] = round(1000 * session.timings["stylize_seconds"], 1)
        self.send(status)

    def render(self, controls: Controls, version: int) -> None:
        session = self.session
        changed_at = time.perf_counter()
        self.show_fast(controls)
        if session.fits_look(controls) and session.shown_look(controls) is None:
            self.fit(controls, version)
            newest = self.controls
            if newest.style_key == controls.style_key:  # the look's first frame, at the newest camera and frame
                self.show_fast(newest)
                self.send(
                    {
                        "type": "fit",
                        "done": True,
                        "seconds": round(session.timings["look_fit_seconds"], 2),
                        "first_look_ms": round(1000 * (time.perf_counter() - changed_at)),
                    }
                )
            if self.version != version:
                return
        quiet_since = time.monotonic()
        while time.monotonic() - quiet_since < IDLE_BEFORE_PATH_TRACING_S:
            if self.version != version:
                return
            time.sleep(0.02)
        for image, samples in session.path_traced_passes(controls):
            if self.version != version or not self.running:
                return
            self.send(frame_message(PATH_TRACED, samples, image))

    def fit(self, controls: Controls, version: int) -> None:
        """Fit the look of ``controls``' style, sending its progress. At the fit's safe points (each step,
        and within the stages before the first: ``stops.checking``) a change of style, strength or mix
        cancels it (``FitCancelled``), and a camera or frame change is shown (with the network), the fit
        waiting while such changes keep coming, so an orbit runs at the fast layer's pace."""
        from ..stops import checking

        shown = version

        def serve() -> None:
            nonlocal shown
            while True:
                newest, newest_version = self.controls, self.version
                if not self.running or newest.style_key != controls.style_key:
                    raise FitCancelled
                if newest_version == shown:
                    return
                shown = newest_version
                self.show_fast(newest)
                still_since = time.monotonic()
                while time.monotonic() - still_since < IDLE_BEFORE_PATH_TRACING_S and self.version == shown:
                    time.sleep(0.02)

        def progress(step: int, steps: int, loss: float) -> None:
            serve()
            self.send({"type": "fit", "step": step, "steps": steps})

        with checking(serve):
            self.session.fit_look(controls, progress)


def build_app(
    session: PreviewSession,
    *,
    style_paths: list[Path],
    density: Path,
    out: Path,
    look: Path | None,
    spec=None,
    host: str | None = None,
    max_uploads: int = MAX_UPLOADS,
    max_uploads_bytes: int = MAX_UPLOADS_BYTES,
):
    """The aiohttp application of the preview (module docstring). ``spec``: the ``job.OutputSpec`` of the
    page's runs (None: the default one), whose settings are the session pipeline's; ``host``: the address it
    was told to listen on (``--host``), a ``Host`` it answers besides the socket's own address;
    ``max_uploads`` and ``max_uploads_bytes``: what a run keeps of uploads."""
    from aiohttp import web

    preview = PreviewApp(
        session,
        style_paths,
        Jobs(out, density, look, session.pipeline.settings, spec),
        host,
        Uploads(max_uploads, max_uploads_bytes),
    )

    @web.middleware
    async def guard(request, handler):  # aiohttp takes a function marked as a middleware, not a method
        return await preview.guard(request, handler)

    app = web.Application(client_max_size=80 * 1024 * 1024, middlewares=[guard])
    app.router.add_get("/", preview.page)
    app.router.add_get(r"/thumb/{index:\d+}.jpg", preview.thumbnail)
    app.router.add_post("/upload", preview.upload)
    app.router.add_post(r"/job/{kind:final|look}", preview.job)
    app.router.add_get("/ws", preview.websocket)
    app.on_startup.append(preview.started)
    app.on_cleanup.append(preview.stopped)
    return app


class PreviewApp:
    """The page's handlers and what they share: the session, the open pages (websockets), the worker
    thread that renders the newest controls, this run's token, the uploads kept and the page's jobs."""

    def __init__(self, session: PreviewSession, style_paths: list[Path], jobs: Jobs, host: str | None, uploads):
        self.session, self.style_paths, self.jobs, self.host, self.uploads = session, style_paths, jobs, host, uploads
        self.sockets: set = set()
        self.loop = None
        self.token = secrets.token_urlsafe(32)
        self.upload_lock = asyncio.Lock()  # one upload at a time: the caps are checked and kept together
        self.worker = Worker(session, self.send)

    def send(self, message) -> None:
        """From the worker thread: to every open page, waiting until sent (so frames never pile up)."""
        if self.loop is None:
            return
        for socket in list(self.sockets):
            coroutine = socket.send_bytes(message) if isinstance(message, bytes) else socket.send_json(message)
            try:
                asyncio.run_coroutine_threadsafe(coroutine, self.loop).result(timeout=5)
            except Exception:  # a closed page: its handler removes it
                pass

    def state(self) -> dict:
        controls, session = self.worker.controls, self.session
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

    async def send_state(self) -> None:
        for socket in list(self.sockets):
            await socket.send_json(self.state())

    async def guard(self, request, handler):
        from aiohttp import web

        transport = request.transport
        why = refusal(
            method=request.method,
            path=request.path,
            headers=request.headers,
            query=request.query,
            local=transport.get_extra_info("sockname") if transport is not None else None,
            host=self.host,
            token=self.token,
        )
        if why is not None:
            return web.json_response({"error": why}, status=403)
        return await handler(request)

    async def page(self, request):
        from aiohttp import web

        text = resources.files("mistyle.preview").joinpath("page.html").read_text()
        text = text.replace(TOKEN_PLACEHOLDER, html.escape(self.token))
        headers = {
            "Cache-Control": "no-store",  # the token is this run's: a cached page would hold a stale one
            "Content-Security-Policy": "frame-ancestors 'none'",  # no other site may frame it and click it
            "X-Frame-Options": "DENY",
        }
        return web.Response(text=text, content_type="text/html", headers=headers)

    async def thumbnail(self, request):
        from aiohttp import web

        index = int(request.match_info["index"])
        if not 0 <= index < len(self.session.styles):
            raise web.HTTPNotFound()
        return web.Response(body=self.session.styles[index].thumbnail, content_type="image/jpeg")

    async def upload(self, request):
        async with self.upload_lock:
            return await self.upload_one(request)

    async def upload_one(self, request):
        from aiohttp import web

        from .session import decode_upload

        full = self.uploads.refusal()
        if full is not None:  # before reading the body: a full server does no work for it
            return web.json_response({"error": full}, status=413)
        try:
            reader = await request.multipart()
            part = await reader.next()
            if part is None or part.name != "style":
                raise ValueError("The upload holds no picture (a form field named 'style').")
            name = part.filename or "upload.png"
            data = bytes(await part.read(decode=False))
            full = self.uploads.refusal(len(data), name)
            if full is not None:
                return web.json_response({"error": full}, status=413)
            style = await asyncio.get_running_loop().run_in_executor(None, decode_upload, name, data)
        except ValueError as error:
            return web.json_response({"error": str(error)}, status=400)
        except Exception as error:  # a malformed request: the page says so, the server goes on
            return web.json_response({"error": f"The upload could not be read ({error})."}, status=400)
        index = len(self.session.styles)
        path = self.uploads.keep(index, style.name, data)
        self.style_paths.append(path)
        self.session.styles.append(style)
        self.worker.update(replace(self.worker.controls, style=index, look=False))
        await self.send_state()
        return web.json_response({"index": index, "name": style.name})

    async def job(self, request):
        from aiohttp import web

        kind = request.match_info["kind"]
        try:
            target = self.jobs.start(kind, self.worker.controls, self.session, self.style_paths)
        except ValueError as error:
            return web.json_response({"error": str(error)}, status=409)
        asyncio.get_running_loop().create_task(self.watch(kind, target))
        return web.json_response({"started": kind, "path": str(target)})

    async def watch(self, kind: str, target: Path) -> None:
        """Until the page's job ends, then tell every page how it went; a saved look becomes the session's."""
        error = await asyncio.get_running_loop().run_in_executor(None, self.jobs.wait)
        if error is None:
            message = {"type": "job", "kind": kind, "done": True, "path": str(target)}
            if kind == "look":  # the page can apply the look it just saved
                from ..look import Look

                self.session.look = Look.load(target, self.session.stylizer)
                self.jobs.look = target
                await self.send_state()
        else:
            message = {"type": "job", "kind": kind, "error": error}
        for socket in list(self.sockets):
            await socket.send_json(message)

    async def websocket(self, request):
        from aiohttp import WSMsgType, web

        socket = web.WebSocketResponse(max_msg_size=1 << 20)
        await socket.prepare(request)
        self.sockets.add(socket)
        await socket.send_json(self.state())
        self.worker.update(self.worker.controls)  # a first image for the new page
        try:
            async for message in socket:
                if message.type != WSMsgType.TEXT:
                    continue
                try:
                    fields = json.loads(message.data)
                    controls = self.session.checked(controls_from(self.worker.controls, fields, self.session))
                except (ValueError, TypeError, RecursionError) as error:
                    # To this page only, with the state it should show again: nothing of the message was applied.
                    await socket.send_json({"type": "error", "message": f"bad control message: {error}"})
                    await socket.send_json(self.state())
                    continue
                self.worker.update(controls)
        finally:
            self.sockets.discard(socket)
        return socket

    async def started(self, app):
        self.loop = asyncio.get_running_loop()
        self.worker.start()

    async def stopped(self, app):
        self.worker.stop()
        # A daemon thread killed inside Mitsuba at exit aborts the process: let it finish its pass.
        await asyncio.get_running_loop().run_in_executor(None, self.worker.join, 60)
        self.uploads.remove()
