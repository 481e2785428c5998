"""Atomic file writes: a temporary file in the target's folder, then a rename over the target.

The target is always either the previous file or the complete new one, never a partial write,
whatever stops the program (an exception, Ctrl-C). The new file gets the usual permissions
(``0o666`` less the umask; ``mkstemp`` alone would leave ``0o600``).
"""

from __future__ import annotations

import json
import os
import tempfile


def write_atomic(path: str | os.PathLike, data: bytes | str) -> None:
    """Write ``data`` (text is UTF-8 encoded) to ``path``; the folder is created if missing."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data.encode() if isinstance(data, str) else data)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def write_json(path: str | os.PathLike, data, **dump_options) -> None:
    """``write_atomic`` of ``data`` as indented JSON with a final newline."""
    write_atomic(path, json.dumps(data, indent=2, **dump_options) + "\n")
