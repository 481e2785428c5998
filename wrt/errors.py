"""User-facing errors: printed as one line by the CLI, which then exits with code 2."""


class WrtError(Exception):
    """An error caused by the user's input (a scene, a mesh, an option), not by a bug.

    The CLI prints ``wrt: error: <message>`` with no traceback and exits with code 2.
    """


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
        The key inside the table, or None when the table itself is at fault.
    problem : str
        What is wrong, e.g. ``"must be in (0, 180)"``.
    value : object, optional
        The offending value, shown with ``repr``.
    """

    _NO_VALUE = object()

    def __init__(self, file, table, key, problem, value=_NO_VALUE):
        self.file, self.table, self.key, self.problem, self.value = file, table, key, problem, value
        where = ".".join(_printable(part) for part in (table, key) if part)
        if value is not SceneError._NO_VALUE:
            try:
                where += f" = {value!r}"
            except RecursionError:  # a value nested deeper than repr goes
                where += " = (a value nested too deeply to show)"
        file = _printable(str(file))
        super().__init__(f"{file}: {where}: {problem}" if where else f"{file}: {problem}")


def _printable(name: str) -> str:
    """``name`` as is, or quoted with escapes when it holds a newline or another control character,
    so that an error stays one line."""
    return name if name.isprintable() else repr(name)


class MeshFileError(WrtError):
    """A mesh file that is missing, unreadable, empty or not a triangle surface."""
