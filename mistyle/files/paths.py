"""Where mistyle's files go: atomic writes, writable folders, links that lead somewhere.

Every file mistyle writes goes through ``atomic_output``: data lands in a temporary file in the
target directory and is renamed into place only once complete, so a crash or a full disk never
leaves a half-written file that a later run would take for a finished one.
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from pathlib import Path


@contextlib.contextmanager
def atomic_output(path):
    """Yield a temporary path next to ``path``; rename it onto ``path`` if the block succeeds."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix, dir=path.parent)
    except OSError as error:
        raise OSError(f"Cannot write {path}: {error.strerror}. Choose a writable output directory.") from error
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600 files; give the usual permissions
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except OSError as error:
        # numpy's short writes raise "N requested and M written" with no errno: a full disk all the same.
        if error.errno == errno.ENOSPC or "requested and" in str(error):
            where = next(p for p in path.absolute().parents if not p.name.startswith("."))  # not a staging folder
            full = OSError(
                f"The disk under {where} is full; nothing was written. Free space there or choose another --out."
            )
            full.errno = errno.ENOSPC
            raise full from None
        raise
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


def check_writable_dir(directory) -> Path:
    """Create ``directory`` if needed and prove a file can be made in it; ``ValueError`` naming the fix."""
    directory = Path(directory)
    try:
        directory.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=directory):
            pass
    except OSError as error:
        raise ValueError(
            f"Cannot write to the output directory {directory} ({error.strerror or error}); choose another --out."
        ) from None
    return directory


def atomic_write_bytes(path, data: bytes) -> Path:
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
    return Path(path)


def check_link(path: Path, what: str, fix: str) -> None:
    """``ValueError`` naming ``what`` when ``path`` is a symbolic link that leads nowhere: a loop, or a
    link to a file that is gone (``path.exists()`` would only say False, and ``Path.resolve`` raises
    RuntimeError on a loop, so code that resolves an input first should call this before)."""
    try:
        os.stat(path)
    except OSError as error:
        if error.errno == errno.ELOOP:
            raise ValueError(f"{what} {path} is a symbolic link loop (it leads back to itself); {fix}.") from None
        if os.path.islink(path):
            raise ValueError(
                f"{what} {path} is a broken symbolic link (to {os.readlink(path)}, which does not exist); {fix}."
            ) from None


def output_target(out) -> Path:
    """``--out`` as the folder mistyle writes: a symbolic link is followed (an output linked to another
    disk is written there, and the link kept), a broken link or a loop refused before any work."""
    out = Path(out)
    if not os.path.islink(out):
        return out
    check_link(out, "--out", "point --out at a folder, or at a path that does not exist yet")
    return Path(os.path.realpath(out))


def os_error_line(error: OSError, fix: str = "choose a writable output folder") -> str:
    """One line for a failed file operation: mistyle's own message as it is, the system's (``[Errno 30]
    Read-only file system: 'out'``) as what failed, on which path, and ``fix``."""
    if error.errno is None and error.args and isinstance(error.args[0], str):
        return one_line(error)
    where = f" {error.filename}" if error.filename else ""
    return f"cannot write{where}: {error.strerror or error}; {fix}."


def one_line(error: BaseException) -> str:
    text = error.args[0] if error.args and isinstance(error.args[0], str) else str(error)
    return " ".join(text.split()) or type(error).__name__
