"""A report replaces only a report wrt wrote (``wrt.files.report_folder``): ``wrt matrix --report``,
``wrt stress --report`` and the pieces folder of ``wrt rays --export`` never delete a user's file.

Issue 25: ``wrt matrix --report notes`` deleted the user's own file in ``notes/``, ``--report .``
deleted a project's README, features file and references, and ``--report features.toml`` turned
the features file into a folder, each with exit code 0.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wrt.cli import main
from wrt.errors import WrtError
from wrt.files import REPORT_MARK, check_report_folder, report_folder, write_atomic

ROOT = Path(__file__).resolve().parents[2]
OWN = ROOT / "examples" / "own_matrix"
WHITTED = ROOT / "examples" / "whitted" / "refraction.toml"


def tree(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() if p.is_file() else None for p in sorted(folder.rglob("*"))}


def refused(capsys, args, *fragments) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("wrt: error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    for fragment in fragments:
        assert fragment in err, err
    return err


def matrix(own_project: Path, report: Path) -> list[str]:
    return [
        "matrix",
        "balls",
        "--features",
        str(own_project / "features.toml"),
        "--refs",
        str(own_project / "refs"),
        "--report",
        str(report),
    ]


def test_matrix_report_replaces_its_own_report_and_nothing_else(own_project, tmp_path, capsys):
    report = tmp_path / "report"
    assert main(matrix(own_project, report)) == 0  # a new folder
    first = tree(report)
    assert "index.html" in first and REPORT_MARK in first
    assert main(matrix(own_project, report)) == 0  # an earlier report: replaced
    assert set(tree(report)) == set(first)
    capsys.readouterr()

    (report / "my notes.txt").write_text("mine")  # a report the user added to is no longer wrt's alone
    refused(capsys, matrix(own_project, report), "my notes.txt", "name a new or empty folder")
    assert (report / "my notes.txt").read_text() == "mine"

    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(matrix(own_project, empty)) == 0  # an empty folder
    assert (empty / "index.html").is_file()


def test_matrix_report_refuses_a_users_folder_and_a_file(own_project, tmp_path, monkeypatch, capsys):
    notes = tmp_path / "notes"
    notes.mkdir()
    (notes / "todo.txt").write_text("keep me")
    before = tree(tmp_path)
    refused(capsys, matrix(own_project, notes), "todo.txt")
    refused(capsys, matrix(own_project, own_project / "features.toml"), "is a file, not a folder")
    monkeypatch.chdir(own_project)
    refused(capsys, matrix(own_project, Path(".")), "holds files wrt did not write")
    assert tree(tmp_path) == before
    assert (own_project / "features.toml").is_file() and (own_project / "README.md").is_file()


def test_stress_report_refuses_a_users_folder_before_the_work(tmp_path, capsys):
    (tmp_path / "README.md").write_text("a project")
    before = tree(tmp_path)
    refused(capsys, ["stress", "--rays", "100", "--report", str(tmp_path)], "README.md")
    assert tree(tmp_path) == before


def test_rays_export_replaces_only_its_own_pieces(tmp_path, capsys):
    args = ["rays", str(WHITTED), "--pixel", "150", "200", "--export"]
    assert main([*args, str(tmp_path / "rays.vtm")]) == 0
    assert main([*args, str(tmp_path / "rays.vtm")]) == 0  # its own pieces: replaced
    capsys.readouterr()
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "data.vtp").write_text("the user's")
    refused(capsys, [*args, str(tmp_path / "mine.vtm")], "--export", "data.vtp")
    assert (tmp_path / "mine" / "data.vtp").read_text() == "the user's" and not (tmp_path / "mine.vtm").exists()


# --- the mechanism ------------------------------------------------------------------------------


def test_a_failing_report_leaves_the_old_one(tmp_path):
    folder = tmp_path / "r"
    with report_folder(folder, "test") as work:
        write_atomic(Path(work) / "a.txt", "old")
    before = tree(tmp_path)
    with pytest.raises(RuntimeError), report_folder(folder, "test") as work:
        write_atomic(Path(work) / "a.txt", "new")
        raise RuntimeError("the work failed")
    assert tree(tmp_path) == before


def test_a_forged_or_broken_mark_does_not_make_a_report(tmp_path):
    folder = tmp_path / "r"
    folder.mkdir()
    (folder / "thesis.tex").write_text("years of work")
    for mark in ("[" * 100000, json.dumps({"wrt": "report", "files": "thesis.tex"}), "{}", json.dumps([1, 2])):
        (folder / REPORT_MARK).write_text(mark)
        with pytest.raises(WrtError, match="thesis.tex"):
            check_report_folder(folder)
    assert (folder / "thesis.tex").read_text() == "years of work"


NAMES = st.sampled_from(["index.html", "a.png", "notes.txt", "sub", "sub/x.png", "sub/deep/y", REPORT_MARK])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(present=st.sets(NAMES, max_size=5), listed=st.none() | st.lists(NAMES, max_size=6))
def test_a_report_never_deletes_a_file_its_mark_does_not_list(tmp_path_factory, present, listed):
    """Whatever the folder holds and whatever its mark says: either the report is refused and the
    folder is untouched, or every file it held was listed by a valid mark (or it was empty)."""
    folder = tmp_path_factory.mktemp("case") / "report"
    folder.mkdir()
    for name in sorted(present - {REPORT_MARK}):
        path = folder / name
        if any(other.startswith(name + "/") for other in present):  # "sub" beside "sub/x.png": a folder
            path.mkdir(parents=True, exist_ok=True)
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(name)
    if listed is not None:
        (folder / REPORT_MARK).write_text(json.dumps({"wrt": "report", "command": "test", "files": listed}))
    before = tree(folder)
    try:
        with report_folder(folder, "test") as work:
            write_atomic(os.path.join(work, "index.html"), "new")
    except WrtError:
        assert tree(folder) == before
        return
    lost = {name for name, data in before.items() if data is not None and name != REPORT_MARK}
    assert not lost or (listed is not None and lost <= set(listed)), (before, listed)
    assert (folder / "index.html").read_text() == "new"


# --- what a write may replace ---------------------------------------------------------------------


def test_a_write_never_replaces_a_device_or_a_fifo(tmp_path):
    """Renaming a temporary file over /dev/null (as root, --json /dev/null would have) or a FIFO
    replaces it with a plain file: refused, and the special file stays what it was (a FIFO here,
    so that a lost check cannot break the machine)."""
    from wrt.files import check_writable, write_json

    special = str(tmp_path / "pipe")
    os.mkfifo(special)
    mode = os.stat(special).st_mode
    with pytest.raises(WrtError, match="not a file wrt may replace"):
        check_writable(special, option="--json")
    with pytest.raises(WrtError, match="not a file wrt may replace"):
        write_json(special, {"x": 1})
    assert os.stat(special).st_mode == mode


def test_a_symbolic_link_stays_and_its_file_is_replaced(tmp_path):
    from wrt.files import write_json

    (tmp_path / "real.json").write_text("old")
    (tmp_path / "link.json").symlink_to(tmp_path / "real.json")
    write_json(tmp_path / "link.json", {"new": 1})
    assert (tmp_path / "link.json").is_symlink()
    assert json.loads((tmp_path / "real.json").read_text()) == {"new": 1}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.json", "real.json"]


def test_matrix_json_refuses_a_fifo_before_the_work(tmp_path, capsys):
    """(A FIFO, not /dev/null itself: were the check ever lost, the test must not break the machine.)"""
    pipe = tmp_path / "pipe"
    os.mkfifo(pipe)
    refused(capsys, ["matrix", "raycast_sphere", "--json", str(pipe)], "is a FIFO")
    assert not pipe.is_file() and pipe.exists()
