"""Files in and out: atomic, checked writes; bounded reads; report folders that replace only reports.

Writes. The target is always either the previous file or the complete new one, never a partial
write, whatever stops the program (an exception, a full disk, Ctrl-C, SIGTERM): the data goes to
a temporary file in the target's folder, every write, flush, close and ``fsync`` is checked, a
writer that cannot report its own errors (OpenImageIO's PNG writer, VTK) has its file read back
by a ``verify`` function, and only then is it renamed over the target. Any failure keeps the old
file and is one ``WrtError`` naming the target and the reason. A new file gets the usual
permissions (``0o666`` less the umask; ``mkstemp`` alone would leave ``0o600``); a replaced one
keeps its own. ``check_writable`` says before any work is done whether a path can be written.

Temporary names carry the writer's process id (``.NAME.PID.XXXXXXXX``): a process killed
mid-write (``kill -9``, a power cut) leaves its temporary file behind, and the next write to the
same target removes those whose process is gone.

Reads. ``read_bytes`` reads a regular file of at most a given size, refusing FIFOs, devices
(``/dev/zero``) and sockets before reading, so that no input can block or exhaust memory;
``check_regular_file`` applies the same test to files another library opens; ``read_json`` and
``read_toml`` add their formats' errors, deep nesting included.

Report folders. ``report_folder`` builds a report (the matrix's HTML, the stress suite's tables)
in a fresh folder and moves it into place. The folder it replaces must be absent, empty, or a
report wrt wrote: one holding the mark ``REPORT_MARK`` and only the files that mark lists. Any
other folder, and a path that is a file, is refused before the work starts, so a report never
deletes what a user keeps.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import stat
import tempfile
from collections.abc import Callable, Iterator

import tomllib

from .errors import WrtError, shorten

NAME_MAX = 255  # bytes in a file name (Linux, macOS, Windows)
RANDOM_CHARS = 8  # what mkstemp appends to the prefix
MAX_TEXT_BYTES = 64 << 20
"""Largest text input wrt reads: a scene, features or faults file, an XML fragment, a spectrum, JSON."""
REPORT_MARK = ".wrt-report.json"
"""The file wrt writes into every report folder: which command wrote it and the files it holds."""


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
    """Remove temporary files and folders of writes to the same target whose process is gone."""
    with contextlib.suppress(OSError):
        for entry in os.listdir(folder):
            if not (entry.startswith(stem) and entry.endswith(suffix)):
                continue
            pid = entry[len(stem) :].split(".", 1)[0]
            if pid.isdigit() and int(pid) != os.getpid() and _process_gone(int(pid)):
                stale = os.path.join(folder, entry)
                if os.path.isdir(stale) and not os.path.islink(stale):
                    shutil.rmtree(stale, ignore_errors=True)
                else:
                    with contextlib.suppress(OSError):
                        os.unlink(stale)


def _reason(error: OSError) -> str:
    return error.strerror or str(error)


def _target(path: str, shown: str) -> str:
    """The file a write to ``path`` replaces: ``path`` itself, or the file a symbolic link there
    points to (the link stays a link). ``WrtError`` naming ``shown`` when that exists and is not a
    regular file or a folder: renaming over a device (``/dev/null``, ``/dev/stdout``), a FIFO or a
    socket would replace it with a plain file."""
    target = os.path.realpath(path) if os.path.islink(path) else path
    try:
        mode = os.stat(path).st_mode  # through the links: /dev/stdout may end in a pipe
    except OSError:
        return target  # absent (it is made), or the write says why
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        raise WrtError(f"{shown}: is {_kind(mode)}, not a file wrt may replace")
    return target


def check_writable(path: str | os.PathLike, *, protect: tuple = (), option: str | None = None) -> None:
    """Raise ``WrtError`` naming ``path`` (after ``option``, when given) when it cannot be written:
    its folder is missing or not writable, it is a folder, a device, a FIFO or a socket, its name
    is longer than ``NAME_MAX`` bytes, or it is one of the files in ``protect`` (the input being
    read). A symbolic link is judged by the file it points to, which a write replaces."""
    shown = f"{option} {os.fspath(path)}" if option else os.fspath(path)
    path = _target(os.fspath(path), shown)
    folder, name = os.path.split(os.path.abspath(path))
    if not name or os.path.isdir(path):
        raise WrtError(f"{shown}: is a folder, not a file name")
    if len(name.encode()) > NAME_MAX:
        raise WrtError(f"{shown}: file name longer than {NAME_MAX} bytes")
    if not os.path.isdir(folder):
        raise WrtError(f"{shown}: folder {folder} does not exist")
    probe_folder(folder, shown)
    for other in protect:
        if os.path.exists(path) and os.path.exists(other) and os.path.samefile(path, other):
            raise WrtError(f"{shown}: is the input {os.fspath(other)}; refusing to overwrite it")


def probe_folder(folder: str, shown: str) -> None:
    """``WrtError`` naming ``shown`` unless a file can be made in ``folder``: tried, by making and
    removing an empty temporary file (permission bits do not stop root, and a read-only or
    pseudo file system such as ``/proc`` answers only to a real attempt)."""
    try:
        fd, probe = tempfile.mkstemp(prefix=".wrt-probe.", dir=folder)
    except OSError as e:
        raise WrtError(f"{shown}: folder {folder} is not writable ({_reason(e)})") from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(probe)


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask


def _fsync(path: str) -> None:
    """Flush ``path``'s data to the disk (``OSError`` when the disk refuses it)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_path(
    path: str | os.PathLike, suffix: str = "", *, verify: Callable[[str], None] | None = None
) -> Iterator[str]:
    """A temporary file beside ``path`` (same folder, which must exist; name
    ``.NAME.PID.XXXXXXXX`` + ``suffix``) for the block to write. When the block ends normally the
    file is synced to disk, checked by ``verify(tmp)`` (which raises when the file is not what was
    meant to be written), and renamed over ``path``; when anything raises (Ctrl-C included) it is
    removed and ``path`` is left as it was. Errors of the file system (a full disk, a read-only
    folder) are ``WrtError`` naming ``path``. Stale temporary files of dead writers to ``path``
    are removed first. A symbolic link ``path`` stays: the file it points to is replaced; a
    device, FIFO or socket there is refused (``_target``)."""
    shown = os.fspath(path)
    path = _target(shown, shown)
    folder, name = os.path.split(os.path.abspath(path))
    stem = _temp_stem(name, suffix)
    _remove_stale(folder, stem, suffix)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f"{stem}{os.getpid()}.", suffix=suffix, dir=folder)
    except OSError as e:
        raise WrtError(f"{shown}: cannot write ({_reason(e)})") from None
    os.close(fd)
    try:
        yield tmp
        try:
            _fsync(tmp)
            if verify is not None:
                verify(tmp)
            try:
                mode = stat.S_IMODE(os.stat(path).st_mode)  # a replaced file keeps its permissions
            except FileNotFoundError:
                mode = 0o666 & ~_umask()
            os.chmod(tmp, mode)
            os.replace(tmp, path)
        except OSError as e:
            raise WrtError(f"{shown}: cannot write ({_reason(e)}); the file was left as it was") from None
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_atomic(path: str | os.PathLike, data: bytes | str) -> None:
    """Write ``data`` (text is UTF-8 encoded) to ``path`` atomically, every byte checked (see
    ``atomic_path``); the folder is created if missing."""
    path = os.fspath(path)
    try:
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    except OSError as e:
        raise WrtError(f"{path}: cannot make its folder ({_reason(e)})") from None
    data = data.encode() if isinstance(data, str) else data
    with atomic_path(path) as tmp:
        try:
            with open(tmp, "wb") as f:  # close() raises when the last flush fails
                f.write(data)
        except OSError as e:
            raise WrtError(f"{path}: cannot write ({_reason(e)}); the file was left as it was") from None


def write_json(path: str | os.PathLike, data, **dump_options) -> None:
    """``write_atomic`` of ``data`` as indented JSON with a final newline."""
    write_atomic(path, json.dumps(data, indent=2, **dump_options) + "\n")


# --- reading ------------------------------------------------------------------------------------


def _unreadable(path: str, what: str, error: OSError) -> str:
    if isinstance(error, FileNotFoundError):
        return f"{path}: cannot read {what} file (no such file)"
    if os.path.isdir(path):
        return f"{path}: is a folder, not a {what} file"
    return f"{path}: cannot read {what} file ({_reason(error)})"


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def _refusal(path: str, what: str, st: os.stat_result, limit: int) -> str | None:
    """Why the file of status ``st`` is not read as ``what``, or None."""
    if not stat.S_ISREG(st.st_mode):
        return f"{path}: is {_kind(st.st_mode)}, not a {what} file"
    if st.st_size > limit:
        return f"{path}: {what} file of {st.st_size} bytes, larger than the {limit} bytes wrt reads"
    return None


def check_regular_file(path: str | os.PathLike, what: str, *, limit: int, error: type[WrtError] = WrtError) -> None:
    """Raise ``error`` naming ``path`` unless it is a regular file of at most ``limit`` bytes (a
    FIFO, a device such as ``/dev/zero`` or a socket would block or never end): the check before
    another library (OpenImageIO, VTK) opens it. ``what`` names the file's role ("scene")."""
    path = os.fspath(path)
    try:
        st = os.stat(path)
    except OSError as e:
        raise error(_unreadable(path, what, e)) from None
    problem = _refusal(path, what, st, limit)
    if problem:
        raise error(problem)


def read_bytes(
    path: str | os.PathLike, what: str, *, limit: int = MAX_TEXT_BYTES, error: type[WrtError] = WrtError
) -> bytes:
    """The contents of the regular file ``path``, at most ``limit`` bytes.

    The file is opened without blocking and its kind and size checked before a byte is read; no
    more than ``limit + 1`` bytes are ever read (``/proc`` files report a size of 0). Raises
    ``error`` naming ``path`` and ``what`` it was to be when it is missing, unreadable, not a
    regular file (a FIFO, a device, a socket, a folder) or larger than ``limit``. Messages never
    quote the contents.
    """
    path = os.fspath(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as e:
        raise error(_unreadable(path, what, e)) from None
    try:
        problem = _refusal(path, what, os.fstat(fd), limit)
        if problem:
            raise error(problem)
        chunks, size = [], 0
        while size <= limit:
            chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as e:
        raise error(f"{path}: cannot read {what} file ({_reason(e)})") from None
    finally:
        os.close(fd)
    if size > limit:
        raise error(f"{path}: {what} file larger than the {limit} bytes wrt reads")
    return b"".join(chunks)


def read_json(path: str | os.PathLike, what: str, *, limit: int = MAX_TEXT_BYTES, error: type[WrtError] = WrtError):
    """The JSON document in ``path`` (``read_bytes``); ``error`` naming the file, and the line and
    column, when it is not JSON or is nested too deeply to read. Its shape is the caller's to check."""
    path = os.fspath(path)
    data = read_bytes(path, what, limit=limit, error=error)
    try:
        return json.loads(data.decode("utf-8"))
    except UnicodeDecodeError as e:
        raise error(f"{path}: not a {what} file: not UTF-8 text (byte {e.start})") from None
    except json.JSONDecodeError as e:
        raise error(f"{path}: not a {what} file: not JSON (line {e.lineno}, column {e.colno}: {e.msg})") from None
    except RecursionError:
        raise error(f"{path}: not a {what} file: JSON nested too deeply") from None


UTF8_BOM = b"\xef\xbb\xbf"  # as Windows editors begin a text file; a second one is text

_TOML_KEYS = re.compile(
    r"(Cannot declare|Cannot mutate immutable namespace|Cannot redefine namespace|Duplicate inline table key) "
    r"(.*?)((?: twice)? \(at [^()]*\))$",
    re.DOTALL,
)


class TomlError(WrtError):
    """A file that is not valid TOML; ``problem`` says why (``not valid TOML: ...``)."""

    def __init__(self, path: str, problem: str):
        self.path, self.problem = path, problem
        super().__init__(f"{path}: {problem}")


def read_toml(path: str | os.PathLike, what: str, *, limit: int = MAX_TEXT_BYTES) -> dict:
    """The TOML document in ``path`` (``read_bytes``; a leading UTF-8 byte-order mark is
    dropped). ``TomlError`` when it is not UTF-8 text, not TOML, holds an integer of more digits
    than Python converts, or is nested too deeply to parse; tomllib's message, with the keys of
    the file it quotes cut by ``wrt.errors.shorten``."""
    path = os.fspath(path)
    data = read_bytes(path, what, limit=limit).removeprefix(UTF8_BOM)
    try:
        return tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError as e:
        raise TomlError(path, f"not valid TOML: not UTF-8 text (byte {e.start})") from None
    except tomllib.TOMLDecodeError as e:
        found = _TOML_KEYS.fullmatch(str(e))
        message = f"{found[1]} {shorten(found[2])}{found[3]}" if found else str(e)
        raise TomlError(path, f"not valid TOML: {message}") from None
    except ValueError:  # an integer of more digits than Python converts (sys.get_int_max_str_digits)
        raise TomlError(path, "not valid TOML: an integer of too many digits") from None
    except RecursionError:  # tomllib recurses once per level of [ or {
        raise TomlError(path, "not valid TOML: arrays or inline tables nested too deeply") from None


# --- report folders -----------------------------------------------------------------------------


def _listing(folder: str) -> set[str]:
    """Every entry under ``folder``, files and folders, as paths relative to it ('/'-separated)."""
    found = set()
    for top, dirs, files in os.walk(folder):
        rel = os.path.relpath(top, folder)
        for entry in dirs + files:
            found.add(entry if rel == "." else f"{rel}/{entry}".replace(os.sep, "/"))
    return found


def _report_files(folder: str) -> set[str] | None:
    """The files the mark of the report in ``folder`` lists, or None when it has no valid mark."""
    mark = os.path.join(folder, REPORT_MARK)
    if not os.path.isfile(mark) or os.path.islink(mark):
        return None
    try:
        doc = read_json(mark, "report mark", limit=1 << 20)
    except WrtError:
        return None
    files = doc.get("files") if isinstance(doc, dict) and doc.get("wrt") == "report" else None
    if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
        return None
    return set(files)


def check_report_folder(folder: str | os.PathLike, option: str = "--report") -> None:
    """Raise ``WrtError`` unless a report may be written to ``folder``: it does not exist (its
    parent folders are made, or can be), it is an empty folder, or it is a report wrt wrote (its
    ``REPORT_MARK`` lists everything in it: a file added since would be lost, so it is refused).
    Called before the work, and again just before the report replaces the folder."""
    folder = os.fspath(folder)
    shown = f"{option} {folder}"
    if os.path.lexists(folder) and not os.path.isdir(folder):
        raise WrtError(f"{shown}: is a file, not a folder; name a new folder for the report")
    if os.path.islink(folder):
        raise WrtError(f"{shown}: is a symbolic link; name the folder itself")
    if os.path.isdir(folder):
        try:
            present = _listing(folder)
        except OSError as e:
            raise WrtError(f"{shown}: cannot be read ({_reason(e)})") from None
        listed = _report_files(folder)
        if present and (listed is None or not present <= listed | {REPORT_MARK}):
            kept = sorted(present - (listed or set()) - {REPORT_MARK})
            shown_files = ", ".join(repr(f) for f in kept[:3]) + (", ..." if len(kept) > 3 else "")
            raise WrtError(
                f"{shown}: holds files wrt did not write there ({shown_files}); wrt replaces only a folder it wrote "
                "itself: name a new or empty folder"
            )
    _check_makeable(folder, shown)


def _check_makeable(folder: str, shown: str) -> None:
    """``WrtError`` naming ``shown`` unless ``folder`` (a folder, or to be made) can be written in:
    the nearest folder at or above it that exists must be writable, and nothing on the way a file."""
    parent = os.path.abspath(folder)
    while not os.path.isdir(parent):
        if os.path.lexists(parent):
            raise WrtError(f"{shown}: {parent} is a file, not a folder")
        parent = os.path.dirname(parent)
    probe_folder(parent, shown)


def check_output_folder(folder: str | os.PathLike, names=(), *, option: str, protect: tuple = ()) -> None:
    """``WrtError`` (naming ``option`` and the path) unless a command can write the files ``names``
    into ``folder``, before its work: ``folder`` is absent and can be made (``_check_makeable``),
    or it is a writable folder in which each of ``names`` can be written (``check_writable``: not
    a folder, a device or one of the inputs ``protect``). Only those files are written; nothing
    else in the folder is touched."""
    folder = os.fspath(folder)
    shown = f"{option} {folder}"
    if os.path.lexists(folder) and not os.path.isdir(folder):
        raise WrtError(f"{shown}: is a file, not a folder")
    _check_makeable(folder, shown)
    if os.path.isdir(folder):
        for name in names:
            check_writable(os.path.join(folder, name), option=option, protect=protect)


@contextlib.contextmanager
def report_folder(folder: str | os.PathLike, command: str, option: str = "--report") -> Iterator[str]:
    """A new, empty folder beside ``folder`` for the block to fill with a report of ``command``
    ("wrt matrix"). When the block ends normally, the mark ``REPORT_MARK`` listing what it holds
    is written, and the folder replaces ``folder`` (``check_report_folder`` is asked again
    first), whose old report is then removed. When the block raises, the new folder is removed
    and ``folder`` is left as it was."""
    folder = os.path.abspath(os.fspath(folder))
    check_report_folder(folder, option)
    parent = os.path.dirname(folder)
    try:
        os.makedirs(parent, exist_ok=True)
        stem = _temp_stem(os.path.basename(folder), "")
        _remove_stale(parent, stem, "")
        work = tempfile.mkdtemp(prefix=f"{stem}{os.getpid()}.", dir=parent)
        os.chmod(work, 0o777 & ~_umask())  # mkdtemp's 0o700 is for temporary folders, not for a report
    except OSError as e:
        raise WrtError(f"{option} {folder}: cannot make the report ({_reason(e)})") from None
    aside = None
    try:
        yield work
        files = sorted(_listing(work))
        write_json(os.path.join(work, REPORT_MARK), {"wrt": "report", "command": command, "files": files})
        check_report_folder(folder, option)
        try:
            if os.path.isdir(folder):
                aside = tempfile.mkdtemp(prefix=f"{stem}{os.getpid()}.old.", dir=parent)
                os.rename(folder, os.path.join(aside, "report"))
            os.rename(work, folder)
        except OSError as e:
            raise WrtError(f"{option} {folder}: cannot move the report into place ({_reason(e)})") from None
    except BaseException:
        if aside is not None and not os.path.exists(folder):  # put the old report back
            with contextlib.suppress(OSError):
                os.rename(os.path.join(aside, "report"), folder)
        shutil.rmtree(work, ignore_errors=True)
        if aside is not None:
            shutil.rmtree(aside, ignore_errors=True)
        raise
    if aside is not None:
        shutil.rmtree(aside, ignore_errors=True)
