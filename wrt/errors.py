"""User-facing errors: printed as one line by the CLI, which then exits with code 2.

A message names the file and says what is wrong with it; it never echoes the file's content
beyond a short token: `token` (a quoted value) and `shorten` (a name or tag inside a message's
own quotes) show at most ``MAX_QUOTED`` characters of it, control characters escaped, and
`foreign` does the same for the messages of the libraries that read files for wrt (VTK,
OpenImageIO), which may quote them.
"""

import re

MAX_QUOTED = 32
"""Most characters of a file's content (a value, a name, a line) an error message shows; longer
text is cut, and "..." says so."""

MAX_LISTED = 8
"""Most names of a file (materials, groups) a message lists as the known ones."""

_ELLIPSIS = "..."


class WrtError(Exception):
    """An error caused by the user's input (a scene, a mesh, an option), not by a bug.

    The CLI prints ``wrt: error: <message>`` with no traceback and exits with code 2.
    """


def _text(content) -> str:
    return content.decode("utf-8", errors="replace") if isinstance(content, (bytes, bytearray)) else str(content)


def shorten(content, limit: int = MAX_QUOTED) -> str:
    """``content`` (text, or bytes read as UTF-8) as a message shows it unquoted: its first
    ``limit`` characters, control characters (and backslashes) escaped as ``repr`` writes them
    (``\\x1b``, ``\\n``), followed by "..." when it was longer."""
    text = _text(content)
    return repr(text[:limit])[1:-1] + (_ELLIPSIS if len(text) > limit else "")


def token(content, limit: int = MAX_QUOTED) -> str:
    """``content`` (text, or bytes read as UTF-8) as a message quotes it: ``repr`` of its first
    ``limit`` characters (control characters escaped), followed by "..." when it was longer.
    Text of at most ``limit`` characters is shown exactly as ``repr`` shows it."""
    text = _text(content)
    return repr(text[:limit]) + (_ELLIPSIS if len(text) > limit else "")


MAX_SHOWN = 4 * MAX_QUOTED
"""Most characters of a value that is not a string (a number, a list, a table) a message shows;
the strings inside it are shown by `token`."""


def shown(value, limit: int = MAX_SHOWN) -> str:
    """A value of a file (a string, a number, a list, a table) as a message shows it: a string
    as its `token`; anything else as ``repr`` writes it, its strings by `token`, cut to
    ``limit`` characters ("..." says so)."""
    text = _shown(value, limit + 1)
    return text if len(text) <= limit else text[:limit] + _ELLIPSIS


def _shown(value, room: int) -> str:
    """`shown` of ``value`` before the cut: at least ``room`` characters when it is longer (so the
    walk ends after ``room`` characters, however large or deeply nested the value)."""
    if isinstance(value, str):
        return token(value)
    if isinstance(value, dict):
        items = [(token(k) if isinstance(k, str) else repr(k)) + ": " for k in value]
        opening, closing, items = "{", "}", [(k, v) for k, v in zip(items, value.values())]
    elif isinstance(value, (list, tuple)):
        opening, closing = ("[", "]") if isinstance(value, list) else ("(", ")")
        items = [("", v) for v in value]
    elif isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 4 * room:
        return f"(an integer of {value.bit_length()} bits)"  # more digits than room; repr may refuse it
    else:
        return repr(value)
    text = opening
    for i, (key, item) in enumerate(items):
        if len(text) >= room:
            return text
        text += (", " if i else "") + key + _shown(item, room - len(text))
    return text + closing


def listed(names, limit: int = MAX_LISTED) -> str:
    """Names of a file (``[[material]]`` names, say), each shown by `shorten`, comma-separated, the
    first ``limit`` of them and "..." for the rest."""
    names = list(names)
    words = [shorten(name) for name in names[:limit]]
    return ", ".join(words + ([_ELLIPSIS] if len(names) > limit else []))


_COLON = re.compile(r":\s+")


def foreign(message: str) -> str:
    """The message of another library that read a file for wrt (VTK, OpenImageIO), fit for one
    of wrt's: its first line, and of that, what follows its first ``: `` (where these libraries
    quote the file: "Unrecognized keyword: <a word of the file>") cut by `shorten`, as is all of a
    line longer than ``3 * MAX_QUOTED`` characters without one."""
    line = (message.strip().splitlines() or ["unknown error"])[0].strip()
    found = _COLON.search(line)
    if found is None:
        return shorten(line, 3 * MAX_QUOTED)
    return shorten(line[: found.start()], 3 * MAX_QUOTED) + ": " + shorten(line[found.end() :])


class SceneError(WrtError):
    """A scene file that cannot be used, naming the file, the table, the key and the value.

    Parameters
    ----------
    file : str
        The scene file.
    table : str or None
        The TOML table, e.g. ``"camera"`` or ``"shape[2]"`` (index in file order), or None when
        the file as a whole is at fault.
    key : str or None
        The key inside the table, or None when the table itself is at fault (cut by `shorten`: a
        key is the file's).
    problem : str
        What is wrong, e.g. ``"must be in (0, 180)"``.
    value : object, optional
        The offending value, as `shown` shows it (a string cut to ``MAX_QUOTED`` characters).
    """

    _NO_VALUE = object()

    def __init__(self, file, table, key, problem, value=_NO_VALUE):
        self.file, self.table, self.key, self.problem, self.value = file, table, key, problem, value
        where = ".".join(part for part in (table and _printable(table), key and shorten(key)) if part)
        if value is not SceneError._NO_VALUE:
            where += f" = {shown(value)}"
        file = _printable(str(file))
        super().__init__(f"{file}: {where}: {problem}" if where else f"{file}: {problem}")


def _printable(name: str) -> str:
    """``name`` as is, or quoted with escapes when it holds a newline or another control character,
    so that an error stays one line."""
    return name if name.isprintable() else repr(name)


class MeshFileError(WrtError):
    """A mesh file that is missing, unreadable, empty or not a triangle surface."""
