"""Atomic file writes: a temporary file in the target's folder, then a rename over the target.

The target is always either the previous file or the complete new one, never a partial write,
whatever stops the program (an exception, Ctrl-C, SIGTERM). A new file gets the usual
permissions (``0o666`` less the umask; ``mkstemp`` alone would leave ``0o600``); a replaced one
keeps its own. ``check_writable`` says before any work is done whether a path can be written.

Temporary names carry the writer's process id (``.NAME.PID.XXXXXXXX``): a process killed
mid-write (``kill -9``, a power cut) leaves its temporary file behind, and the next write to the
same target removes those whose process is gone.
"""

from __future__ import annotations

import contextlib
import json
import os
import stat
import tempfile
from collections.abc import Iterator

from .errors import WrtError

NAME_MAX = 255  # bytes in a file name (Linux, macOS, Windows)
RANDOM_CHARS = 8  # what mkstemp appends to the prefix


def _temp_stem(name: str, suffix: str) -> str:
    """``.NAME.``, NAME shortened so that a temporary name (``.NAME.PID.XXXXXXXX`` + suffix) fits
    in ``NAME_MAX`` bytes."""
    extra = len(f"..{os.getpid()}.") + RANDOM_CHARS + len(suffix.encode())
    while name and len(name.encode()) + extra > NAME_MAX:
        name = name[:-1]
    return "." + name + "."


def _process_gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except (PermissionError, OSError, OverflowError):
        return False  # alive (someone else's), or not ours to judge
    return False


def _remove_stale(folder: str, stem: str, suffix: str) -> None:
    """Remove temporary files of writes to the same target whose process is gone."""
    for entry in os.listdir(folder):
        if not (entry.startswith(stem) and entry.endswith(suffix)):
            continue
        pid = entry[len(stem) :].split(".", 1)[0]
        if pid.isdigit() and int(pid) != os.getpid() and _process_gone(int(pid)):
            with contextlib.suppress(OSError):
                os.unlink(os.path.join(folder, entry))


def check_writable(path: str | os.PathLike, *, protect: tuple = ()) -> None:
    """Raise ``WrtError`` naming ``path`` when it cannot be written: its folder is missing or not
    writable, it is a folder, its name is longer than ``NAME_MAX`` bytes, or it is one of the
    files in ``protect`` (the input being read)."""
    path = os.fspath(path)
    folder, name = os.path.split(os.path.abspath(path))
    if not name or os.path.isdir(path):
        raise WrtError(f"{path}: is a folder, not a file name")
    if len(name.encode()) > NAME_MAX:
        raise WrtError(f"{path}: file name longer than {NAME_MAX} bytes")
    if not os.path.isdir(folder):
        raise WrtError(f"{path}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise WrtError(f"{path}: folder {folder} is not writable")
    for other in protect:
        if os.path.exists(path) and os.path.exists(other) and os.path.samefile(path, other):
            raise WrtError(f"{path}: is the input {os.fspath(other)}; refusing to overwrite it")


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str = "") -> Iterator[str]:
    """A temporary file beside ``path`` (same folder, which must exist; name
    ``.NAME.PID.XXXXXXXX`` + ``suffix``) for the block to write; renamed over ``path`` when the
    block ends normally, removed when it raises (Ctrl-C included). Stale temporary files of
    dead writers to ``path`` are removed first."""
    folder, name = os.path.split(os.path.abspath(path))
    stem = _temp_stem(name, suffix)
    _remove_stale(folder, stem, suffix)
    fd, tmp = tempfile.mkstemp(prefix=f"{stem}{os.getpid()}.", suffix=suffix, dir=folder)
    os.close(fd)
    try:
        yield tmp
        try:
            mode = stat.S_IMODE(os.stat(path).st_mode)  # a replaced file keeps its permissions
        except FileNotFoundError:
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o666 & ~umask
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_atomic(path: str | os.PathLike, data: bytes | str) -> None:
    """Write ``data`` (text is UTF-8 encoded) to ``path``; the folder is created if missing."""
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        f.write(data.encode() if isinstance(data, str) else data)


def write_json(path: str | os.PathLike, data, **dump_options) -> None:
    """``write_atomic`` of ``data`` as indented JSON with a final newline."""
    write_atomic(path, json.dumps(data, indent=2, **dump_options) + "\n")
