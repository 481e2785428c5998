"""Atomic file writes: a temporary file in the target's folder, then a rename over the target.

The target is always either the previous file or the complete new one, never a partial write,
whatever stops the program (an exception, Ctrl-C, SIGTERM). A new file gets the usual
permissions (``0o666`` less the umask; ``mkstemp`` alone would leave ``0o600``); a replaced one
keeps its own. ``check_writable`` says before any work is done whether a path can be written.
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
TEMP_EXTRA = 10  # bytes mkstemp adds around the prefix: "." and 8 random characters, then "."


def _temp_prefix(name: str, suffix: str) -> str:
    """``.NAME.``, NAME shortened so that the temporary name fits in ``NAME_MAX`` bytes."""
    while name and len(name.encode()) + len(suffix.encode()) + TEMP_EXTRA > NAME_MAX:
        name = name[:-1]
    return "." + name + "."


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
    """A temporary file beside ``path`` (same folder, which must exist; name ``.NAME.XXXX`` +
    ``suffix``) for the block to write; renamed over ``path`` when the block ends normally,
    removed when it raises (Ctrl-C included)."""
    folder, name = os.path.split(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(name, suffix), suffix=suffix, dir=folder)
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
