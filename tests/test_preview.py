"""mistyle-preview without a browser: the session's images and the server's routes, on a tiny network.

The browser itself is ``tests/test_preview_browser.py`` (``make test-browser``).
"""

import asyncio
import io
import json
import struct
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

from mistyle.preview.server import build_app, controls_from
from mistyle.preview.session import (
    PASS_SPP,
    Camera,
    Controls,
    PreviewSession,
    Style,
    decode_upload,
    thumbnail_jpeg,
)
from mistyle.stylizer import Stylizer


@pytest.fixture(scope="module")
def session(tmp_path_factory, tiny_checkpoint_factory, blob_density):
    checkpoint = tiny_checkpoint_factory(tmp_path_factory.mktemp("ckpt") / "tiny.pt")
    rng = np.random.default_rng(0)
    styles = []
    for name, colour in (("red.png", (0.6, 0.1, 0.1)), ("blue.png", (0.1, 0.2, 0.6))):
        image = np.clip(rng.random((32, 32, 3)) * 0.3 + np.asarray(colour), 0, 1).astype(np.float32)
        styles.append(Style(name, image, thumbnail_jpeg(image)))
    return PreviewSession(Stylizer(checkpoint), [blob_density, blob_density[::-1].copy()], styles, res=64)


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
    moved = controls_from(Controls(), {"camera": [1, 0.5, 3], "mix_with": None, "strength": "0.5"})
    assert moved.camera == Camera(1.0, 0.5, 3.0) and moved.strength == 0.5
    with pytest.raises(ValueError):
        controls_from(Controls(), {"camera": [1, 2]})


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


def test_the_server_serves_the_page_frames_and_only_its_styles(mi, session, tmp_path):
    from aiohttp import FormData
    from aiohttp.test_utils import TestClient, TestServer

    paths = [tmp_path / style.name for style in session.styles]

    async def scenario():
        app = build_app(session, style_paths=list(paths), density=tmp_path / "d.vol", out=tmp_path / "out", look=None)
        async with TestClient(TestServer(app)) as client:
            page = await client.get("/")
            assert page.status == 200 and "mistyle preview" in await page.text()
            assert (await client.get("/thumb/1.jpg")).status == 200
            assert (await client.get("/thumb/2.jpg")).status == 404
            assert (await client.get("/thumb/..%2F..%2Fetc%2Fpasswd")).status == 404
            socket = await client.ws_connect("/ws")
            state = await socket.receive_json()
            assert state["styles"] == ["red.png", "blue.png"] and state["frames"] == 2
            while True:
                message = await asyncio.wait_for(socket.receive(), 120)
                if message.type.name == "BINARY":
                    break
            kind, samples = struct.unpack("<B3xI", message.data[:8])
            assert kind == 0 and samples == 0 and message.data[8:10] == b"\xff\xd8"
            await socket.send_str("not json")
            assert "bad control message" in json.dumps(await next_json(socket))
            form = FormData()
            form.add_field("style", b"garbage", filename="bad.png")
            answer = await client.post("/upload", data=form)
            assert answer.status == 400 and "bad.png" in (await answer.json())["error"]
            buffer = io.BytesIO()
            Image.fromarray(np.full((16, 16, 3), 90, np.uint8)).save(buffer, format="PNG")
            form = FormData()
            form.add_field("style", buffer.getvalue(), filename="grey.png")
            answer = await client.post("/upload", data=form)
            assert answer.status == 200 and (await answer.json())["index"] == 2
            assert (await client.get("/thumb/2.jpg")).status == 200
            await socket.close()

    async def next_json(socket):
        while True:
            message = await asyncio.wait_for(socket.receive(), 120)
            if message.type.name == "TEXT" and json.loads(message.data)["type"] == "error":
                return json.loads(message.data)

    asyncio.run(scenario())
    del session.styles[2:]
