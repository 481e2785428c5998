"""Atomic file writes: a temporary file in the target's folder, then a rename over the target.

The target is always either the previous file or the complete new one, never a partial write,
whatever stops the program (an exception, Ctrl-C). The new file gets the usual permissions
(``0o666`` less the umask; ``mkstemp`` alone would leave ``0o600``).
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str = "") -> Iterator[str]:
    """A temporary file beside ``path`` (same folder, which must exist; name ``.NAME.XXXX`` +
    ``suffix``) for the block to write; renamed over ``path`` when the block ends normally,
    removed when it raises (Ctrl-C included)."""
    folder, name = os.path.split(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix="." + name + ".", suffix=suffix, dir=folder)
    os.close(fd)
    try:
        yield tmp
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
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
