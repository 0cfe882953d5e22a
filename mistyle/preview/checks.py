"""What the preview's server accepts: which pages may drive it (its hosts, the origin and this run's token:
``refusal``), the uploads it keeps (``Uploads``) and the control messages of a page, checked (``controls_from``).
``server``'s docstring says why each is so."""

from __future__ import annotations

import ipaddress
import math
import re
import secrets
import shutil
import tempfile
from dataclasses import replace
from pathlib import Path

from .session import Camera, Controls, PreviewSession

TOKEN_HEADER = "X-Mistyle-Token"
MAX_UPLOADS = 20
"""Uploads one server run keeps (module docstring: more are refused with 413)."""
MAX_UPLOADS_BYTES = 128 * 1024 * 1024
"""Bytes of the uploads one server run keeps, in all (each one is limited by ``session.MAX_UPLOAD_BYTES``)."""
CONTROL_NAMES = ("style", "mix_with", "mix", "strength", "frame", "look", "camera")


def safe_name(name: str) -> str:
    """``name`` with anything but letters, digits, ``_``, ``.`` and ``-`` replaced: a file name of the server's."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


def url_host(address: str) -> str:
    """``address`` as a URL writes it: an IPv6 address in brackets."""
    return f"[{address}]" if ":" in address and not address.startswith("[") else address


def is_loopback(address: str) -> bool:
    try:
        ip = ipaddress.ip_address(address.split("%")[0])
    except ValueError:
        return False
    mapped = getattr(ip, "ipv4_mapped", None)  # ::ffff:127.0.0.1 on a dual-stack socket
    return ip.is_loopback or (mapped is not None and mapped.is_loopback)


def allowed_hosts(local: tuple | None, host: str | None) -> set[str]:
    """The ``Host`` values of a request that arrived on the socket address ``local`` (``(address, port,
    ...)``): that address, localhost's names when it is loopback, and ``host`` (``--host``), each with
    the port (and without it on port 80, as browsers send it)."""
    if not local:
        return set()
    address, port = str(local[0]), int(local[1])
    names = {url_host(address)}
    if is_loopback(address):
        names |= {"127.0.0.1", "localhost", "[::1]"}
    if host:
        names.add(url_host(host))
    allowed = {f"{name}:{port}".lower() for name in names}
    if port == 80:
        allowed |= {name.lower() for name in names}
    return allowed


def refusal(*, method: str, path: str, headers, query, local: tuple | None, host: str | None, token: str) -> str | None:
    """Why a request may not reach the preview (module docstring: Host, Origin, token), or ``None``."""
    hosts = allowed_hosts(local, host)
    shown = ", ".join(sorted(hosts)) or "none"
    sent_host = headers.get("Host")
    if sent_host is None:
        return f"The request has no Host header; send the server's address ({shown})."
    if sent_host.lower() not in hosts:
        return (
            f"Host {sent_host[:100]!r} is not this server's address ({shown}); "
            "open the page at the URL mistyle-preview printed."
        )
    origin = headers.get("Origin")
    if origin is not None and origin.lower() not in {f"http://{name}" for name in hosts}:
        own = f"http://{sent_host.lower()}"
        return f"Origin {origin[:100]!r} is not this preview's page ({own}); only the page it serves may drive it."
    public = method in ("GET", "HEAD") and (path == "/" or path.startswith("/thumb/"))
    if not public:  # the page and thumbnails only: a route added later needs the token from the start
        sent = headers.get(TOKEN_HEADER) or query.get("token")
        if not sent:
            return (
                f"{method} {path} needs this server run's token, in the {TOKEN_HEADER} header or a 'token' "
                'query parameter; the page carries it in <meta name="mistyle-token">.'
            )
        if not secrets.compare_digest(sent.encode(), token.encode()):
            return (
                f"The token of {method} {path} is not this server run's; reload the page "
                "(a page from an earlier run of mistyle-preview holds an old one)."
            )
    return None


class Uploads:
    """The pictures uploaded in one server run, kept in a temporary folder for the page's runs: at most
    ``max_count`` files and ``max_bytes`` in all (module docstring)."""

    def __init__(self, max_count: int = MAX_UPLOADS, max_bytes: int = MAX_UPLOADS_BYTES):
        self.max_count, self.max_bytes = int(max_count), int(max_bytes)
        self.folder: Path | None = None  # made at the first upload
        self.sizes: list[int] = []

    def refusal(self, size: int = 0, name: str = "the upload") -> str | None:
        """Why one more upload of ``size`` bytes may not be kept, or ``None``."""
        used = sum(self.sizes)
        advice = "restart mistyle-preview to upload more, or put the pictures in a folder given to --styles."
        if len(self.sizes) >= self.max_count:
            return f"This preview keeps {self.max_count} uploads at most and has {len(self.sizes)}; {advice}"
        if used + size > self.max_bytes:
            return (
                f"{name} ({size / 2**20:.1f} MB) would take the uploads past {self.max_bytes / 2**20:.0f} MB "
                f"({used / 2**20:.1f} MB kept); {advice}"
            )
        return None

    def keep(self, index: int, name: str, data: bytes) -> Path:
        if self.folder is None:
            self.folder = Path(tempfile.mkdtemp(prefix="mistyle-preview-styles-"))
        path = self.folder / f"{index:03d}_{safe_name(name)}"
        path.write_bytes(data)
        self.sizes.append(len(data))
        return path

    def remove(self) -> None:
        if self.folder is not None:
            shutil.rmtree(self.folder, ignore_errors=True)


def shown(value) -> str:
    """``value`` as a JSON-ish text short enough for a message."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def checked_number(name: str, value) -> float:
    """``value`` as a finite float; ``ValueError`` naming ``name`` otherwise (a bool is not a number)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{name} {shown(value)} is not a number; send a JSON number.")
    try:
        result = float(value)
    except OverflowError:
        result = math.inf
    if not math.isfinite(result):
        raise ValueError(f"{name} {shown(value)} is not a finite number; send a finite JSON number.")
    return result


def checked_index(name: str, value, count: int | None, what: str) -> int:
    """``value`` as an index into ``count`` things (``None``: any from 0); ``ValueError`` otherwise."""
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"{name} {shown(value)} is not an integer; send the index of one of the {what}.")
    if value < 0 or (count is not None and value >= count):
        bounds = f"0 to {count - 1}" if count is not None else "0 or more"
        raise ValueError(f"{name} {shown(value)} is not one of the {what} ({bounds}).")
    return value


def controls_from(current: Controls, fields, session: PreviewSession | None = None) -> Controls:
    """``current`` with the fields a page sent (a JSON object of ``style``, ``mix_with``, ``mix``,
    ``strength``, ``frame``, ``look``, ``camera``: ``[azimuth, elevation, distance]``).

    Every field is checked, and against ``session``'s styles, frames and look when given; the camera is
    then clamped to the orbit by ``session.checked``, as the page clamps it.

    Raises:
        ValueError: an unknown field or a bad value, named with what it takes; nothing of the message
            is applied."""
    if not isinstance(fields, dict):
        raise ValueError(f"a control message is a JSON object of {', '.join(CONTROL_NAMES)}; got {shown(fields)}.")
    unknown = sorted(str(name) for name in fields if name not in CONTROL_NAMES)
    if unknown:
        raise ValueError(f"unknown control {shown(unknown[0])}; the controls are {', '.join(CONTROL_NAMES)}.")
    styles = len(session.styles) if session is not None else None
    changes = {}
    if "style" in fields:
        changes["style"] = checked_index("style", fields["style"], styles, "styles")
    if "mix_with" in fields and fields["mix_with"] is not None:
        try:
            changes["mix_with"] = checked_index("mix_with", fields["mix_with"], styles, "styles")
        except ValueError as error:
            raise ValueError(f"{error} Send null for no second style.") from None
    elif "mix_with" in fields:
        changes["mix_with"] = None
    for name in ("mix", "strength"):
        if name in fields:
            value = checked_number(name, fields[name])
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"{name} {shown(fields[name])} is outside 0 to 1.")
            changes[name] = value
    if "frame" in fields:
        frames = len(session.frames) if session is not None else None
        changes["frame"] = checked_index("frame", fields["frame"], frames, "frames")
    if "look" in fields:
        value = fields["look"]
        if not isinstance(value, bool):
            raise ValueError(f"look {shown(value)} is not true or false.")
        if value and session is not None and session.look is None:
            raise ValueError("look true: this preview has no look; start it with --look or save one (Save look).")
        changes["look"] = value
    if "camera" in fields:
        camera = fields["camera"]
        if not isinstance(camera, (list, tuple)) or len(camera) != 3:
            raise ValueError(f"camera {shown(camera)} is not [azimuth, elevation, distance].")
        azimuth, elevation, distance = (
            checked_number(f"camera {part}", value) for part, value in zip(("azimuth", "elevation", "distance"), camera)
        )
        if distance <= 0:
            raise ValueError(f"camera distance {shown(camera[2])} is not positive.")
        changes["camera"] = Camera(azimuth, elevation, distance)
    return replace(current, **changes)
