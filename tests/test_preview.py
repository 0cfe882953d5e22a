"""mistyle-preview without a browser: the session's images and the server's routes, on a tiny network.

The browser itself is ``tests/test_preview_browser.py`` (``make test-browser``).
"""

import asyncio
import contextlib
import io
import json
import re
import struct
import threading
import time
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

from mistyle.pipeline import Pipeline, PipelineSettings
from mistyle.preview.checks import controls_from
from mistyle.preview.jobs import Jobs
from mistyle.preview.server import build_app
from mistyle.preview.session import (
    PASS_SPP,
    Camera,
    Controls,
    PreviewSession,
    StyleOption,
    decode_upload,
    thumbnail_jpeg,
)


@pytest.fixture(scope="module")
def session(tmp_path_factory, tiny_checkpoint_factory, blob_density):
    checkpoint = tiny_checkpoint_factory(tmp_path_factory.mktemp("ckpt") / "tiny.pt")
    rng = np.random.default_rng(0)
    styles = []
    for name, colour in (("red.png", (0.6, 0.1, 0.1)), ("blue.png", (0.1, 0.2, 0.6))):
        image = np.clip(rng.random((32, 32, 3)) * 0.3 + np.asarray(colour), 0, 1).astype(np.float32)
        styles.append(StyleOption(name, image, thumbnail_jpeg(image)))
    pipeline = Pipeline(PipelineSettings(checkpoint=checkpoint, look_steps=3))
    return PreviewSession(pipeline, [blob_density, blob_density[::-1].copy()], styles, res=64)


def test_images_follow_the_controls(mi, session):
    controls = session.checked(session.initial_controls())
    first = session.layer_image(controls)
    assert first.shape == (64, 64, 3) and first.max() > 0.01
    stylized = session.stylized
    turned = session.layer_image(replace(controls, camera=Camera(1.0, 0.3, 2.0)))
    assert session.stylized == stylized, "a camera move reuses the albedo"
    assert np.abs(turned - first).mean() > 1e-3
    blue = Controls(style=1, camera=controls.camera)
    assert np.abs(session.layer_image(blue) - first).mean() > 1e-3 and session.stylized == stylized + 1
    other_frame = Controls(style=1, frame=1, camera=controls.camera)
    assert not np.array_equal(session.albedo(other_frame), session.albedo(blue))
    image, samples = next(session.path_traced_passes(blue))
    assert samples == PASS_SPP and image.shape == (64, 64, 3) and image.max() > 0.01


def test_the_look_the_page_fits_is_the_final_renders_bit_for_bit(mi, tmp_path, tiny_checkpoint_factory, blob_density):
    """At full strength the page fits, in its worker's thread, the look that *Render final output* fits
    with the page's render options; the albedo it then shows is what ``mistyle-render`` writes."""
    from mistyle import render_final
    from mistyle.files import load_style, read_vol
    from mistyle.preview import page_settings
    from mistyle.preview import parser as preview_parser

    checkpoint = tiny_checkpoint_factory(tmp_path / "tiny.pt")
    density, style_path = tmp_path / "blob.npy", tmp_path / "warm.png"
    np.save(density, blob_density)
    rng = np.random.default_rng(1)
    Image.fromarray((rng.random((24, 24, 3)) * [255, 160, 60]).astype(np.uint8)).save(style_path)
    image = load_style(style_path)
    options = ["--look-steps", "3", "--checkpoint", str(checkpoint), "--res", "16", "--spp", "2", "--denoise", "none"]
    preview_options = ["--density", str(density), "--render-options", " ".join(options)]
    settings, _ = page_settings(preview_parser().parse_args(preview_options), style_path)
    styles = [StyleOption("warm.png", image, thumbnail_jpeg(image))]
    session = PreviewSession(Pipeline(settings), [blob_density], styles, res=32)
    controls = session.checked(session.initial_controls())
    assert session.fits_look(controls) and session.shown_look(controls) is None
    network = session.albedo(controls)
    steps = []
    fitting = threading.Thread(target=session.fit_look, args=(controls, lambda step, total, loss: steps.append(step)))
    fitting.start()
    fitting.join()
    assert steps == [1, 2, 3] and session.shown_look(controls) is not None
    shown = session.albedo(controls)
    assert np.abs(shown - network).mean() > 1e-3
    weaker = replace(controls, strength=0.5)
    assert not session.fits_look(weaker) and session.shown_look(weaker) is None, "a weakened style fits no look"
    out = tmp_path / "out"
    arguments = ["--density", str(density), "--style", str(style_path), "--out", str(out), "--quiet", *options]
    assert render_final.main(arguments) == 0
    np.testing.assert_array_equal(read_vol(out / "albedo_refined.vol"), shown)


def test_the_pages_runs_write_a_look_and_an_output_in_a_process_of_their_own(mi, session, tmp_path, blob_density):
    """*Save look* and *Render final output* run ``job.render_outputs`` in a process of their own, with the
    page's controls and settings (no ``mistyle-render`` command line): the look file, then the output
    folder; a look saved again under the same name is refused with one line, and the file is kept."""
    from mistyle.files import write_png, write_vol
    from mistyle.job import OutputSpec
    from mistyle.look import is_look_file
    from mistyle.pipeline import RenderSettings
    from mistyle.preview.jobs import Jobs

    density = write_vol(tmp_path / "blob.vol", blob_density)
    paths = [write_png(tmp_path / option.name, option.image, srgb=False) for option in session.styles]
    settings = replace(session.pipeline.settings, render=RenderSettings(res=16, spp=2, denoise="none"))
    jobs = Jobs(tmp_path / "out", density, None, settings, OutputSpec())
    controls = session.checked(session.initial_controls())
    look = jobs.start("look", controls, session, paths)
    assert jobs.wait() is None and is_look_file(look)
    final = jobs.start("final", replace(controls, strength=0.5), session, paths)
    assert jobs.wait() is None and (final / "report.json").is_file() and (final / "sheet.png").is_file()
    report = json.loads((final / "report.json").read_text())
    assert report["inputs"]["strength"] == 0.5 and report["inputs"]["res"] == 16
    saved = look.read_bytes()
    jobs.start("look", controls, session, paths)
    assert "already exists" in jobs.wait() and look.read_bytes() == saved
    with pytest.raises(ValueError, match="full strength"):
        jobs.start("look", replace(controls, strength=0.5), session, paths)


def test_the_page_carries_a_looks_texture_with_the_sequences_velocities(session, blob_density):
    """A frame of a sequence with velocities shows what the final render makes of it: the look's texture
    carried from the frames before (``advection``), not laid where the box has it."""
    frames = [np.roll(blob_density, t, axis=2) for t in range(3)]
    velocities = [np.broadcast_to(np.float32([1, 0, 0]), blob_density.shape + (3,)) for _ in frames]
    look = session.pipeline.fit_look(frames, session.styles[0].image)
    page = PreviewSession(session.pipeline, frames, session.styles, look=look, res=32, velocities=velocities)
    controls = page.checked(replace(page.initial_controls(), frame=2))
    carried = look.stylize(frames, velocities=velocities)[2]
    np.testing.assert_array_equal(page.albedo(controls), carried)
    assert np.abs(carried - look.apply(frames[2])).mean() > 1e-3


def test_the_page_switches_to_the_look_and_a_new_style_cancels_a_fit(mi, session, tmp_path):
    """The page gets the network's frame at once, then the fit's progress, then the look's frame; a
    camera move during a fit is shown meanwhile, and a style change ends the fit, keeping nothing."""
    slow = Pipeline(replace(session.pipeline.settings, look_steps=40), stylizer=session.stylizer)
    fresh = PreviewSession(slow, session.frames, session.styles[:2], res=32)

    def is_status(kind, data):
        return kind == "TEXT" and data["type"] == "status"

    def is_progress(kind, data):
        return kind == "TEXT" and data["type"] == "fit" and not data.get("done") and data["step"] >= 1

    def is_done(kind, data):
        return kind == "TEXT" and data["type"] == "fit" and data.get("done")

    async def scenario():
        async with served(fresh, tmp_path) as (client, token, _):
            socket = await client.ws_connect("/ws", origin=own_origin(client), params={"token": token})
            assert (await next_message(socket, is_status, 120))["shows"] == "network"
            await next_message(socket, is_progress, 120)
            await socket.send_str(json.dumps({"style": 1}))
            assert (await next_message(socket, is_status, 60))["shows"] == "network"
            assert (await next_message(socket, is_progress, 120))["steps"] == 40
            await socket.send_str(json.dumps({"camera": [1.0, 0.2, 2.0]}))
            seen = []
            done = await next_message(socket, lambda kind, data: seen.append((kind, data)) or is_done(kind, data), 120)
            frames = [index for index, (kind, _) in enumerate(seen) if kind == "BINARY"]
            progress = [index for index, message in enumerate(seen) if is_progress(*message)]
            assert frames and progress and frames[0] < progress[-1], "the camera move is shown during the fit"
            statuses = [data for kind, data in seen if is_status(kind, data)]
            assert statuses[-1]["shows"] == "look" and done["first_look_ms"] >= 1000 * done["seconds"] > 0
            await socket.close()

    asyncio.run(scenario())
    assert fresh.shown_look(Controls(style=1)) is not None
    assert fresh.fits_look(Controls(style=0)) and fresh.shown_look(Controls(style=0)) is None, "the cancelled fit"


def test_a_sequence_starting_empty_shows_its_empty_frames_as_they_are(mi, session, blob_density):
    """Frames before a simulation's emitter starts are shown as they are; the strength and the colour
    match come from the first frame that holds medium, as in the final render."""
    from mistyle.stylizer import EMPTY_FRAME_ALBEDO

    frames = [np.zeros_like(blob_density), *session.frames]
    page = PreviewSession(session.pipeline, frames, session.styles, res=32)
    start = page.checked(page.initial_controls())
    assert page.first == 1 and start.frame == 1  # the page starts where the smoke is
    controls = replace(start, frame=0)
    assert np.all(page.albedo(controls) == EMPTY_FRAME_ALBEDO) and page.layer_image(controls).max() == 0
    for frame in (1, 2):
        shown, alone = (
            one.albedo(replace(controls, frame=frame - offset)) for one, offset in ((page, 0), (session, 1))
        )
        assert np.array_equal(shown, alone)


def test_controls_are_clamped_to_what_the_session_has(session):
    wild = Controls(style=7, mix_with=9, mix=3.0, strength=-1.0, frame=5, look=True, camera=Camera(0, 5, 100))
    checked = session.checked(wild)
    assert (checked.style, checked.mix_with, checked.mix, checked.strength, checked.frame, checked.look) == (
        1,
        None,
        1.0,
        0.0,
        1,
        False,
    )
    assert checked.camera.elevation <= 1.45 and checked.camera.distance <= 8.0
    moved = controls_from(Controls(), {"camera": [1, 0.5, 3], "mix_with": None, "strength": 0.5})
    assert moved.camera == Camera(1.0, 0.5, 3.0) and moved.strength == 0.5
    with pytest.raises(ValueError, match="camera"):
        controls_from(Controls(), {"camera": [1, 2]})
    with pytest.raises(ValueError, match="strength '0.5' is not a number"):
        controls_from(Controls(), {"strength": "0.5"})


def test_an_upload_goes_through_the_style_decoder(tmp_path):
    buffer = io.BytesIO()
    Image.fromarray(np.full((16, 16, 3), 200, np.uint8)).save(buffer, format="PNG")
    style = decode_upload("grey.png", buffer.getvalue())
    assert style.image.shape == (16, 16, 3) and style.thumbnail[:2] == b"\xff\xd8"
    with pytest.raises(ValueError, match="junk.png"):
        decode_upload("junk.png", b"not a picture")
    with pytest.raises(ValueError, match="smaller than 8x8|at least 8"):
        tiny = io.BytesIO()
        Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(tiny, format="PNG")
        decode_upload("tiny.png", tiny.getvalue())


TOKEN = re.compile(r'<meta name="mistyle-token" content="([^"]*)">')


def png(value: int = 90, side: int = 16) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(np.full((side, side, 3), value, np.uint8)).save(buffer, format="PNG")
    return buffer.getvalue()


def picture_form(data: bytes, name: str = "grey.png"):
    from aiohttp import FormData

    form = FormData()
    form.add_field("style", data, filename=name)
    return form


@pytest.fixture
def jobs_started(monkeypatch):
    """``Jobs.start`` records its kind and starts nothing; the run ends at once, well."""
    kinds = []

    def start(self, kind, controls, session, style_paths):
        kinds.append(kind)
        return self.out / kind

    monkeypatch.setattr(Jobs, "start", start)
    monkeypatch.setattr(Jobs, "wait", lambda self: None)
    return kinds


@contextlib.asynccontextmanager
async def served(session, tmp_path, **options):
    """The preview's app on a real server on an ephemeral loopback port: its client, the token its page
    carries (``None`` when it carries none) and the style paths the server was given."""
    from aiohttp.test_utils import TestClient, TestServer

    paths = [tmp_path / style.name for style in session.styles]
    app = build_app(session, style_paths=paths, density=tmp_path / "d.vol", out=tmp_path / "out", look=None, **options)
    try:
        async with TestClient(TestServer(app)) as client:
            match = TOKEN.search(await (await client.get("/")).text())
            yield client, (match.group(1) if match else None), paths
    finally:
        del session.styles[2:]


def own_origin(client) -> str:
    return f"http://127.0.0.1:{client.port}"


async def next_message(socket, wanted, timeout: float = 60.0):
    """The next websocket message for which ``wanted(type_name, data)`` holds (JSON decoded for text)."""
    deadline = time.monotonic() + timeout
    while True:
        message = await asyncio.wait_for(socket.receive(), max(deadline - time.monotonic(), 0.01))
        data = json.loads(message.data) if message.type.name == "TEXT" else message.data
        if wanted(message.type.name, data):
            return data


def is_error(kind, data):
    return kind == "TEXT" and data["type"] == "error"


def is_state(kind, data):
    return kind == "TEXT" and data["type"] == "state"


def is_frame(kind, data):
    return kind == "BINARY"


async def refused(answer, *words: str) -> str:
    """``answer`` is a 403 whose JSON error names ``words``: its error."""
    assert answer.status == 403, (answer.status, await answer.text())
    error = (await answer.json())["error"]
    for word in words:
        assert word in error, (word, error)
    return error


def test_the_server_serves_the_page_frames_and_only_its_styles(mi, session, tmp_path):
    async def scenario():
        async with served(session, tmp_path) as (client, token, _):
            page = await client.get("/")
            assert page.status == 200 and "mistyle preview" in await page.text()
            assert page.headers["Cache-Control"] == "no-store" and "frame-ancestors 'none'" in str(page.headers)
            assert (await client.get("/thumb/1.jpg")).status == 200
            assert (await client.get("/thumb/2.jpg")).status == 404
            assert (await client.get("/thumb/..%2F..%2Fetc%2Fpasswd")).status == 404
            socket = await client.ws_connect("/ws", origin=own_origin(client), params={"token": token})
            state = await socket.receive_json()
            assert state["styles"] == ["red.png", "blue.png"] and state["frames"] == 2
            message = await next_message(socket, is_frame, 120)
            kind, samples = struct.unpack("<B3xI", message[:8])
            assert kind == 0 and samples == 0 and message[8:10] == b"\xff\xd8"
            await socket.send_str("not json")
            assert "bad control message" in (await next_message(socket, is_error))["message"]
            headers = {"X-Mistyle-Token": token, "Origin": own_origin(client)}
            answer = await client.post("/upload", data=picture_form(b"garbage", "bad.png"), headers=headers)
            assert answer.status == 400 and "bad.png" in (await answer.json())["error"]
            answer = await client.post("/upload", data=picture_form(png()), headers=headers)
            assert answer.status == 200 and (await answer.json())["index"] == 2
            assert (await client.get("/thumb/2.jpg")).status == 200
            await socket.close()

    asyncio.run(scenario())


def test_a_page_of_another_site_cannot_open_the_websocket(session, tmp_path):
    from aiohttp import WSServerHandshakeError

    async def scenario():
        async with served(session, tmp_path) as (client, token, _):
            foreign = ("http://evil.example", "null", "http://127.0.0.1:1", f"https://127.0.0.1:{client.port}")
            for origin in foreign:
                with pytest.raises(WSServerHandshakeError) as error:
                    await client.ws_connect("/ws", origin=origin, params={"token": token or "x"})
                assert error.value.status == 403, origin

    asyncio.run(scenario())


def test_a_page_of_another_site_cannot_upload_nor_start_a_render(session, tmp_path, jobs_started):
    async def scenario():
        async with served(session, tmp_path) as (client, token, paths):
            headers = {"Origin": "http://evil.example", "X-Mistyle-Token": token or "x"}
            answer = await client.post("/upload", data=picture_form(png()), headers=headers)
            await refused(answer, "Origin 'http://evil.example'", own_origin(client))
            for kind in ("final", "look"):
                await refused(await client.post(f"/job/{kind}", headers=headers), "evil.example")
            assert len(session.styles) == 2 and len(paths) == 2 and jobs_started == []

    asyncio.run(scenario())


def test_another_host_gets_nothing_not_even_the_page(session, tmp_path, jobs_started):
    """DNS rebinding: another site's name resolving to loopback sends that name as Host (and Origin)."""
    from aiohttp import WSServerHandshakeError

    async def scenario():
        async with served(session, tmp_path) as (client, token, _):
            rebound = f"evil.example:{client.port}"
            headers = {"Host": rebound, "Origin": f"http://{rebound}", "X-Mistyle-Token": token or "x"}
            page = await client.get("/", headers={"Host": rebound})
            error = await refused(page, f"Host '{rebound}'", f"127.0.0.1:{client.port}")
            assert token is None or token not in error
            await refused(await client.get("/thumb/0.jpg", headers={"Host": rebound}), "Host")
            await refused(await client.post("/upload", data=picture_form(png()), headers=headers), "Host")
            await refused(await client.post("/job/final", headers=headers), "Host")
            with pytest.raises(WSServerHandshakeError) as refusal:
                await client.ws_connect("/ws", headers=headers, params={"token": token or "x"})
            assert refusal.value.status == 403
            assert len(session.styles) == 2 and jobs_started == []

    asyncio.run(scenario())


def test_the_websocket_and_posts_need_the_server_runs_token(session, tmp_path, jobs_started):
    from aiohttp import WSServerHandshakeError

    async def scenario():
        async with served(session, tmp_path) as (client, token, _):
            for origin in (None, own_origin(client)):  # a script sends no Origin; the page its own
                for params in ({}, {"token": "wrong"}):
                    with pytest.raises(WSServerHandshakeError) as refusal:
                        await client.ws_connect("/ws", origin=origin, params=params)
                    assert refusal.value.status == 403, (origin, params)
                for headers in ({}, {"X-Mistyle-Token": "wrong"}):
                    headers = headers | ({"Origin": origin} if origin else {})
                    answer = await client.post("/upload", data=picture_form(png()), headers=headers)
                    await refused(answer, "token")
                    await refused(await client.post("/job/final", headers=headers), "token")
            assert len(session.styles) == 2 and jobs_started == []

    asyncio.run(scenario())


def test_the_page_with_its_origin_and_token_still_drives_the_preview(mi, session, tmp_path, jobs_started):
    async def scenario():
        async with served(session, tmp_path) as (client, token, _):
            assert token and len(token) >= 32, "the page carries the server run's token"
            socket = await client.ws_connect("/ws", origin=own_origin(client), params={"token": token})
            assert (await next_message(socket, is_state))["styles"] == ["red.png", "blue.png"]
            await next_message(socket, is_frame, 120)
            headers = {"Origin": own_origin(client), "X-Mistyle-Token": token}
            answer = await client.post("/upload", data=picture_form(png()), headers=headers)
            assert answer.status == 200 and (await answer.json())["index"] == 2
            assert (await next_message(socket, is_state))["styles"][2] == "grey.png"
            answer = await client.post("/job/final", headers=headers)
            assert answer.status == 200 and jobs_started == ["final"]
            done = await next_message(socket, lambda kind, data: kind == "TEXT" and data["type"] == "job")
            assert done["done"] and done["kind"] == "final"
            await socket.close()
            local = f"localhost:{client.port}"  # the other name of loopback, as typed in the address bar
            page = await client.get("/", headers={"Host": local, "Origin": f"http://{local}"})
            assert page.status == 200
            answer = await client.post("/job/final", headers={"Host": local, "X-Mistyle-Token": token})
            assert answer.status == 200, await answer.text()

    asyncio.run(scenario())


def test_a_server_run_keeps_a_bounded_number_and_size_of_uploads(session, tmp_path):
    picture = png()

    async def scenario(limits, refusal_words):
        async with served(session, tmp_path, **limits) as (client, token, paths):
            headers = {"X-Mistyle-Token": token}
            for number in range(2):
                answer = await client.post("/upload", data=picture_form(picture, f"{number}.png"), headers=headers)
                assert answer.status == 200, await answer.text()
            answer = await client.post("/upload", data=picture_form(picture, "third.png"), headers=headers)
            assert answer.status == 413, await answer.text()
            error = (await answer.json())["error"]
            assert all(word in error for word in refusal_words), error
            assert len(session.styles) == 4 and len(paths) == 4
            kept = paths[2:]
            assert all(path.is_file() for path in kept)
        assert not any(path.exists() for path in kept) and not kept[0].parent.exists(), "removed at exit"

    asyncio.run(scenario({"max_uploads": 2}, ["2 uploads at most", "--styles"]))
    bytes_cap = {"max_uploads": 10, "max_uploads_bytes": 2 * len(picture) + len(picture) // 2}
    asyncio.run(scenario(bytes_cap, ["third.png", "MB", "--styles"]))


BAD_CONTROLS = [
    ('{"strength": NaN}', "strength nan is not a finite number"),
    ('{"mix": Infinity}', "mix inf"),
    ('{"strength": 2}', "strength 2 is outside 0 to 1"),
    ('{"style": 7}', "style 7 is not one of the styles (0 to 1)"),
    ('{"style": "1"}', "style '1' is not an integer"),
    ('{"mix_with": -1}', "mix_with -1"),
    ('{"frame": 1.5}', "frame 1.5 is not an integer"),
    ('{"frame": 2}', "frame 2 is not one of the frames (0 to 1)"),
    ('{"look": true}', "no look"),
    ('{"look": "false"}', "look 'false' is not true or false"),
    ('{"camera": [0, Infinity, 2]}', "camera elevation"),
    ('{"camera": [0, 0.1, -2]}', "camera distance -2"),
    ('{"camera": "far"}', "camera 'far'"),
    ('{"colour": 1}', "unknown control 'colour'"),
    ("[1, 2]", "a control message is a JSON object"),
    ('{"strength": 0.5, "style": 9}', "style 9"),  # nothing of a bad message is applied
    ("[" * 100_000 + "]" * 100_000, "bad control message"),
]


def test_a_bad_control_message_is_answered_to_its_page_only_and_changes_nothing(mi, session, tmp_path):
    async def scenario():
        async with served(session, tmp_path) as (client, token, _):
            connect = dict(origin=own_origin(client), params={"token": token})
            sender, other = await client.ws_connect("/ws", **connect), await client.ws_connect("/ws", **connect)
            seen = []  # everything the other page gets

            async def collect():
                async for message in other:
                    seen.append(message)

            collector = asyncio.get_running_loop().create_task(collect())
            before = (await next_message(sender, is_state))["controls"]
            for text, words in BAD_CONTROLS:
                await sender.send_str(text)
                error = await next_message(sender, is_error, 10)
                assert words in error["message"] and "bad control message" in error["message"], (text, error)
                assert (await next_message(sender, is_state, 10))["controls"] == before, text
            mark = len(seen)
            await sender.send_str(json.dumps({"strength": 0.5, "style": 1}))
            await sender.send_str('{"style": -1}')  # answered after the good one: its state shows it applied
            controls = (await next_message(sender, is_state, 10))["controls"]
            assert (controls["strength"], controls["style"]) == (0.5, 1)
            deadline = time.monotonic() + 60
            while not any(message.type.name == "BINARY" and message.data[0] == 0 for message in seen[mark:]):
                assert time.monotonic() < deadline, "the other page gets the new fast-layer frame"
                await asyncio.sleep(0.02)
            texts = [json.loads(message.data) for message in seen if message.type.name == "TEXT"]
            assert texts and not [text for text in texts if text["type"] == "error"], texts
            await sender.close()
            await other.close()
            await collector

    asyncio.run(scenario())


def test_a_signal_stops_the_server_and_is_reported_as_the_commands_stop():
    import os
    import signal
    import time

    from mistyle.preview import serve

    suite = signal.signal(signal.SIGINT, signal.default_int_handler)  # as a command started from a terminal
    try:
        for number in (signal.SIGTERM, signal.SIGINT):
            before = signal.getsignal(number)
            assert serve(lambda number=number: (os.kill(os.getpid(), number), time.sleep(10))) == number
            assert signal.getsignal(number) is before  # the command's handlers are put back
        assert serve(lambda: None) is None
    finally:
        signal.signal(signal.SIGINT, suite)


def test_render_options_may_start_with_a_dash():
    from mistyle.preview import joined_render_options, parser

    argv = joined_render_options(["--density", "d.vol", "--render-options", "--vdb", "--port", "0"])
    args = parser().parse_args(argv)
    assert args.render_options == "--vdb" and args.port == 0
    assert joined_render_options(["--render-options"]) == ["--render-options"]  # argparse names what is missing
