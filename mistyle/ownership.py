"""What mistyle may replace or delete: only files it can prove it wrote, and only while it alone writes.

Every output folder mistyle makes (a render, a batch's root, a training run, a dataset, a benchmark
folder) carries a manifest, ``.mistyle-manifest.json``: each file it wrote there with its size,
modification time and SHA-256. A later run replaces such a folder, or a file in it, only when every
file in it is one the manifest lists, unchanged (size and mtime, else the hash); a file a user added
or edited makes the run refuse with one line naming it. Nothing else on disk is ever deleted.

One run writes an output at a time. The lock ``.NAME.lock`` beside the output is an ``flock``ed
file: the kernel frees it when its process dies, so a lock left by a killed run is free, and only
the holder removes the file (while still holding it; a waiter then sees a lock that is no longer
the file at that path and takes the new one). Staging folders beside the output
(``.NAME.partial-*``, ``.NAME.replaced-*``, ``.NAME.chunk-*``) carry their run's identity in the
name (pid, process start time, host): a later run removes one only when that process is provably
gone, on this host.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
import socket
import tempfile
from pathlib import Path

MANIFEST_FILE = ".mistyle-manifest.json"
MANIFEST_FORMAT = "mistyle-manifest/1"
STAGING_KINDS = ("partial", "replaced", "chunk")
_SHOWN = 4  # foreign files named in a message


# ------------------------------------------------------------------------- who a run is
def _host() -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", socket.gethostname()) or "host"


def process_start(pid: int) -> int | None:
    """The start time of process ``pid`` in clock ticks since boot (Linux ``/proc``), None where unknown."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    # The command name (field 2) may hold spaces and parentheses: count fields after its last ")".
    return int(stat.rpartition(")")[2].split()[19])


def run_identity() -> str:
    """``PID-START-HOST``: names this process for as long as it lives, and never another one."""
    return f"{os.getpid()}-{process_start(os.getpid()) or 0}-{_host()}"


def is_gone(identity: str) -> bool:
    """Whether the run named by ``identity`` (``run_identity``) has provably ended: it ran on this
    host and no process with its pid and start time exists. A run on another host is never gone."""
    match = re.fullmatch(r"(\d+)-(\d+)-([A-Za-z0-9_]+)", identity)
    if match is None or match[3] != _host():
        return False
    pid, start = int(match[1]), int(match[2])
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:
        pass  # another user's live process
    current = process_start(pid)
    return current is not None and start != 0 and current != start  # the pid was reused


# ------------------------------------------------------------------------- the manifest
def _fingerprint(path: Path) -> tuple[int, int]:
    stat = path.stat()
    return stat.st_size, stat.st_mtime_ns


def file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _entries(folder: Path) -> list[str]:
    """Every file under ``folder`` (relative, POSIX), symlinks and empty folders included, but not the
    manifest or a file being written atomically (``io.atomic_output``'s ``.NAME.tmp*``)."""
    found = []
    for root, dirs, files in os.walk(folder):
        base = Path(root).relative_to(folder)
        for name in files + [d for d in dirs if Path(root, d).is_symlink()]:
            relative = (base / name).as_posix()
            if relative != MANIFEST_FILE and not re.fullmatch(r"\..+\.tmp.*", name):
                found.append(relative)
        for name in dirs:
            if not os.listdir(Path(root, name)):
                found.append((base / name).as_posix() + "/")
    return sorted(found)


def read_manifest(folder) -> dict | None:
    """The manifest of ``folder``, or None (none, unreadable, or not mistyle's)."""
    try:
        record = json.loads((Path(folder) / MANIFEST_FILE).read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    if not isinstance(record, dict) or record.get("format") != MANIFEST_FORMAT:
        return None
    if not isinstance(record.get("files"), dict):
        return None
    return record


def write_manifest(folder, kind: str, names: list[str] | None = None, pending: list[str] = ()) -> None:
    """Record the files mistyle wrote into ``folder``: ``names`` (relative paths; None: every file in
    it), added to what its manifest already lists of files still there. Call it last, once the files
    are complete; a folder whose manifest exists is complete. ``pending``: names about to be written
    under the output's lock (``writing``), taken as mistyle's until the next manifest."""
    folder = Path(folder)
    record = read_manifest(folder) or {}
    files = {name: entry for name, entry in record.get("files", {}).items() if (folder / name).is_file()}
    for name in _entries(folder) if names is None else names:
        path = folder / name
        if path.is_file() and not path.is_symlink():
            size, mtime = _fingerprint(path)
            files[name] = {"size": size, "mtime_ns": mtime, "sha256": file_sha256(path)}
    record = {"format": MANIFEST_FORMAT, "kind": kind, "files": dict(sorted(files.items()))}
    if pending:
        record["pending"] = sorted(pending)
    data = json.dumps(record, indent=1)
    fd, tmp = tempfile.mkstemp(prefix=f"{MANIFEST_FILE}.", suffix=".tmp", dir=folder)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)  # mkstemp's 0600 would hide it from the farm's other users
        with os.fdopen(fd, "w") as handle:
            handle.write(data + "\n")
        os.replace(tmp, folder / MANIFEST_FILE)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


@contextlib.contextmanager
def writing(folder, kind: str, names: list[str], also_ours=lambda name: False):
    """Around writes of ``names`` into an output ``folder`` that may exist (holding its lock): refused
    (``check_replaceable``) if the folder holds a file mistyle did not write; should the run die half
    way, the next one still knows those files for mistyle's (the manifest's ``pending``)."""
    folder = Path(folder)
    check_replaceable(folder, also_ours=also_ours)
    folder.mkdir(parents=True, exist_ok=True)
    write_manifest(folder, kind, [], pending=names)
    yield
    write_manifest(folder, kind, names)


def _unchanged(path: Path, entry: dict) -> bool:
    if not path.is_file() or path.is_symlink():
        return False
    size, mtime = _fingerprint(path)
    if size != entry.get("size"):
        return False
    return mtime == entry.get("mtime_ns") or file_sha256(path) == entry.get("sha256")


def foreign_files(folder, also_ours=lambda name: False) -> list[str]:
    """The files in ``folder`` that mistyle cannot prove it wrote (absent from its manifest, or changed
    since); ``also_ours(relative path)`` names others the caller accounts for. [] for a missing folder."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    record = read_manifest(folder) or {}
    listed, pending = record.get("files", {}), set(record.get("pending", []))
    return [
        name
        for name in _entries(folder)
        if not also_ours(name)
        and name not in pending
        and not (name in listed and _unchanged(folder / name, listed[name]))
    ]


def is_owned(folder) -> bool:
    """Whether ``folder`` is a complete mistyle output that holds nothing but what mistyle wrote."""
    return read_manifest(folder) is not None and not foreign_files(folder)


def describe_foreign(folder, names: list[str]) -> str:
    """One line for a refusal: which files in ``folder`` mistyle did not write."""
    shown = ", ".join(names[:_SHOWN]) + (f" and {len(names) - _SHOWN} more" if len(names) > _SHOWN else "")
    if read_manifest(folder) is None:
        why = "it has no manifest of mistyle's (a folder mistyle did not write, or an older mistyle's)"
    else:
        why = "mistyle did not write them, or they changed since"
    return f"{folder} holds {shown}: {why}"


def check_replaceable(folder, what: str = "--out", also_ours=lambda name: False) -> None:
    """``ValueError`` (one line, naming the files) unless everything in ``folder`` is mistyle's own."""
    foreign = foreign_files(folder, also_ours)
    if foreign:
        raise ValueError(
            f"{describe_foreign(folder, foreign)}; mistyle replaces only its own files. Move them out, or choose "
            f"another {what}."
        )


def adopt_older(folder, kind: str, layout: re.Pattern) -> bool:
    """Give ``folder`` its manifest if an older mistyle wrote it (no manifest, every file's relative path
    matching ``layout``, the files that kind of folder holds), so that the rule above applies to it
    from now on; whether it did. A folder holding any other file is left as it is (and refused)."""
    folder = Path(folder)
    if not folder.is_dir() or read_manifest(folder) is not None:
        return False
    found = foreign_files(folder)
    if not found or not all(layout.fullmatch(name) for name in found):
        return False
    write_manifest(folder, kind)
    return True


def update_manifest(folder, kind: str, new=(), rewritten=(), add=(), done=()) -> None:
    """Record the files of ``new`` that ``folder``'s manifest does not list yet and every file of
    ``rewritten``, hashing only those (cheap for a folder of many large files that a run adds to), and
    add ``add`` to, or take ``done`` from, its pending names, keeping other runs'. Hold the lock."""
    folder = Path(folder)
    record = read_manifest(folder) or {}
    listed = record.get("files", {})
    names = list(dict.fromkeys([*(n for n in new if n not in listed), *rewritten]))
    pending = (set(record.get("pending", [])) | set(add)) - set(done)
    write_manifest(folder, kind, [name for name in names if (folder / name).is_file()], pending=sorted(pending))


@contextlib.contextmanager
def adding(folder, kind: str, names: list[str], rewritten=(), locked: bool = False):
    """Around a long run that adds ``names`` (relative paths) to the output ``folder``, checked before
    (``check_replaceable``), and may stop half way: they are mistyle's while it runs (pending, with
    other runs'), and however the block ends, those written are recorded (``update_manifest``;
    ``rewritten``: files it may replace). ``locked``: the caller holds the folder's lock for the run;
    otherwise each update takes it, as runs sharing a folder do (a dataset's shards). A folder it made
    is removed again when the block fails before writing anything into it."""
    folder = Path(folder)
    created = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)

    def update(**changes):
        if locked:
            update_manifest(folder, kind, **changes)
            return
        with output_lock(folder, wait=True):
            update_manifest(folder, kind, **changes)

    update(add=names)
    try:
        yield
    except BaseException:
        update(new=names, rewritten=rewritten, done=names)
        if created and not _entries(folder):
            shutil.rmtree(folder, ignore_errors=True)
        raise
    update(new=names, rewritten=rewritten, done=names)


# ------------------------------------------------------------------------- one writer at a time
def _output_path(directory) -> Path:
    directory = Path(directory).absolute()  # "--out ." has no name of its own to stage beside
    if directory.name in ("", ".", ".."):
        directory = directory.resolve()
    return directory


def is_beside_output(relative: str) -> bool:
    """Whether a path (relative to an output's parent folder) is what mistyle keeps beside an output
    while writing it: its lock, a staging folder, or a file in one."""
    kinds = "|".join(STAGING_KINDS)
    return re.fullmatch(rf"\.[^/]+\.(lock|({kinds})-[^/]+)(/.*)?", relative) is not None


def _staging_pattern(name: str) -> re.Pattern:
    return re.compile(re.escape(f".{name}.") + rf"({'|'.join(STAGING_KINDS)})-(\d+-\d+-[A-Za-z0-9_]+)-[^-]+")


def make_staging(directory: Path, kind: str) -> Path:
    """A new empty staging folder of ``kind`` beside ``directory``, named after this run, with the
    usual mode (mkdtemp's is 0700)."""
    staging = Path(tempfile.mkdtemp(prefix=f".{directory.name}.{kind}-{run_identity()}-", dir=directory.parent))
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(staging, 0o777 & ~umask)
    return staging


def remove_dead_staging(directory) -> int:
    """Remove the staging folders beside ``directory`` whose runs have provably ended; their number."""
    directory = _output_path(directory)
    pattern = _staging_pattern(directory.name)
    removed = 0
    with contextlib.suppress(OSError):
        for path in directory.parent.iterdir():
            match = pattern.fullmatch(path.name)
            if match and path.is_dir() and not path.is_symlink() and is_gone(match[2]):
                shutil.rmtree(path, ignore_errors=True)
                removed += not path.exists()
    return removed


def _writable_error(directory: Path, error: OSError) -> ValueError:
    return ValueError(
        f"Cannot write to the output directory {directory} ({error.strerror or error}); choose another --out."
    )


def _holder(lock_path: Path) -> str:
    with contextlib.suppress(OSError, ValueError, UnicodeDecodeError):
        owner = json.loads(lock_path.read_text())
        return f" (pid {owner['pid']} on {owner['host']})"
    return ""


def _lock_path(directory: Path) -> Path:
    """The file whose lock a run holds while it writes ``directory``: beside it, hidden."""
    return directory.parent / f".{directory.name}.lock"


def _in_use(directory: Path, lock_path: Path) -> ValueError:
    return ValueError(
        f"Another mistyle run is writing to {directory}{_holder(lock_path)}; wait for it to finish or "
        "choose another --out."
    )


def check_not_in_use(directory) -> None:
    """``output_lock``'s refusal when another run holds ``directory``'s lock now, said before any work:
    the lock itself is taken when the output is written, after the inputs and the network are loaded."""
    import fcntl

    directory = _output_path(directory)
    lock_path = _lock_path(directory)
    try:
        fd = os.open(lock_path, os.O_RDONLY)
    except OSError:  # no lock file: no run holds it
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError:
        raise _in_use(directory, lock_path) from None
    finally:
        os.close(fd)  # and with it the shared lock, at once


@contextlib.contextmanager
def output_lock(directory, wait: bool = False):
    """Hold the lock of ``directory`` for the block; yield ``(directory, parent)``. A second run into
    the same output is refused while it is held (``wait``: it waits instead). Holding it, the staging
    folders of provably dead runs beside ``directory`` are removed."""
    import fcntl

    directory = _output_path(directory)
    parent = directory.parent
    lock_path = _lock_path(directory)
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise _writable_error(directory, error) from None
    while True:
        try:
            fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as error:
            raise _writable_error(directory, error) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX if wait else fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise _in_use(directory, lock_path) from None
        try:
            same = os.stat(lock_path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)  # its holder removed it as we waited: take the lock file that is there now
    try:
        os.ftruncate(fd, 0)
        os.write(fd, json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "run": run_identity()}).encode())
        if directory.exists() and not directory.is_dir():
            raise ValueError(f"The output path {directory} is a file; choose a folder for --out.")
        removed = remove_dead_staging(directory)
        if removed:
            from .progress import status

            status(f"note: removed {removed} unfinished staging folder(s) of an ended run beside {directory}")
        yield directory, parent
    finally:
        with contextlib.suppress(OSError):
            os.unlink(lock_path)  # still holding it, so no other run holds this file
        os.close(fd)


@contextlib.contextmanager
def staged_directory(directory, kind: str = "render", keep: tuple[str, ...] = ()):
    """Yield an empty staging folder; when the block succeeds, it becomes ``directory`` whole, with its
    manifest (``kind``). An existing ``directory`` is replaced only if it holds nothing but
    mistyle's files (checked again under the lock, as a user may have added one since the run began);
    a failure or an interrupt removes the staging folder and leaves ``directory`` as it was. An
    output whose manifest's kind is in ``keep`` (without ``--overwrite``: a complete render that another
    run finished after this one checked the path) is refused under the lock, before the block's work."""
    with output_lock(directory) as (directory, parent):
        record = read_manifest(directory) if directory.is_dir() else None
        if record is not None and record.get("kind") in keep:
            raise ValueError(
                f"{directory} was written by another mistyle run after this one began; pass --overwrite to "
                "replace it, or choose another --out."
            )
        try:
            staging = make_staging(directory, "partial")
        except OSError as error:
            raise _writable_error(directory, error) from None
        try:
            yield staging
            write_manifest(staging, kind)
            if directory.exists():
                check_replaceable(directory)
                retired = make_staging(directory, "replaced")
                os.replace(directory, retired / directory.name)
                os.replace(staging, directory)
                shutil.rmtree(retired, ignore_errors=True)
            else:
                os.replace(staging, directory)
        finally:
            shutil.rmtree(staging, ignore_errors=True)


@contextlib.contextmanager
def chunk_staging(directory):
    """Yield an empty staging folder beside ``directory`` for one chunk of a sequence, removed after the
    block. It takes no lock: chunks render side by side (on a farm, at once) and each merges its
    files into ``directory`` under ``output_lock(directory, wait=True)`` (``merge_files``)."""
    directory = _output_path(directory)
    try:
        directory.parent.mkdir(parents=True, exist_ok=True)
        staging = make_staging(directory, "chunk")
    except OSError as error:
        raise _writable_error(directory, error) from None
    remove_dead_staging(directory)
    try:
        yield staging
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def merge_files(staging: Path, directory: Path) -> list[str]:
    """Move every file of ``staging`` (``chunk_staging``) into ``directory``, each replacing its namesake
    atomically and keeping the others; returns the names moved. Hold ``output_lock(directory)``, inside
    ``writing(directory, ...)`` (which refuses a folder holding a file mistyle did not write)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    moved = []
    for path in sorted(Path(staging).iterdir()):
        if path.is_file():
            os.replace(path, directory / path.name)
            moved.append(path.name)
    return moved
