"""Every writer on a full file system: the previous file is kept, byte for byte, the command fails
with one line (exit code 2), and no temporary file is left behind.

The file system is a small tmpfs filled to the last byte (``full_disk`` in conftest.py; skipped
where this machine does not allow mounting one). Each output kind is written once while there is
room, then again after the disk is full: EXR, PNG, checkpoints, JSON, the matrix's HTML report,
references, the stress report, the ray view's PNG and its VTK multiblock.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from wrt.cli import main
from wrt.errors import WrtError

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "examples" / "raycast" / "raycast_sphere.toml"
WHITTED = ROOT / "examples" / "whitted" / "refraction.toml"
OWN = ROOT / "examples" / "own_matrix"


def snapshot(folder: Path) -> dict:
    """Every file under ``folder`` (the filler excepted) and its bytes."""
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name != ".filler"
    }


def entries(folder: Path) -> set:
    """Every name under ``folder`` (files and folders), the filler excepted."""
    return {str(p.relative_to(folder)) for p in folder.rglob("*") if p.name != ".filler"}


def refused_on_full_disk(capsys, disk, args):
    """Run ``wrt ARGS`` once with room (it must succeed), then with the disk full: exit code 2, one
    ``wrt: error:`` line naming no traceback, and the disk exactly as after the first run."""
    assert main(args) == 0, capsys.readouterr().err
    capsys.readouterr()
    before, names = snapshot(disk.path), entries(disk.path)
    assert before, "the first run wrote nothing to the disk"
    disk.fill()
    code = main(args)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if not line.startswith("wrt: warning: ")]
    assert code == 2, (code, err)
    assert len(lines) == 1 and lines[0].startswith("wrt: error: ") and "Traceback" not in err, err
    assert snapshot(disk.path) == before, "a file on the full disk changed"
    assert entries(disk.path) == names, "a temporary file or folder was left behind"
    return lines[0]


@pytest.mark.parametrize(
    "name, extra",
    [
        ("good.png", []),
        ("good.exr", ["--aov", "all"]),
        ("half.exr", ["--half"]),
    ],
)
def test_render_keeps_the_old_image(full_disk, capsys, name, extra):
    out = full_disk.path / name
    line = refused_on_full_disk(
        capsys, full_disk, ["render", str(SCENE), "-o", str(out), "--width", "64", "--height", "48", *extra]
    )
    assert str(out) in line


def test_a_checkpoint_on_a_full_disk_stops_the_render_and_keeps_the_old_image(full_disk, capsys):
    out = full_disk.path / "progress.exr"
    args = ["render", str(SCENE), "-o", str(out), "--width", "32", "--height", "24", "--spp", "3"]
    refused_on_full_disk(capsys, full_disk, [*args, "--checkpoint-every", "1"])


def test_ray_view_and_multiblock_keep_the_old_files(full_disk, capsys):
    args = ["rays", str(WHITTED), "--pixel", "150", "200"]
    refused_on_full_disk(capsys, full_disk, [*args, "-o", str(full_disk.path / "view.png")])
    full_disk.free()
    refused_on_full_disk(capsys, full_disk, [*args, "--export", str(full_disk.path / "rays.vtm")])


def own_options(project: Path, refs: Path | None = None) -> list[str]:
    return ["--features", str(project / "features.toml"), "--refs", str(refs or project / "refs")]


def test_matrix_json_and_report_keep_the_old_ones(own_project, full_disk, capsys):
    matrix = ["matrix", "balls", *own_options(own_project)]
    refused_on_full_disk(capsys, full_disk, [*matrix, "--json", str(full_disk.path / "results.json")])
    full_disk.free()
    line = refused_on_full_disk(capsys, full_disk, [*matrix, "--report", str(full_disk.path / "report")])
    assert "report" in line


def test_references_keep_the_old_ones(own_project, full_disk, capsys):
    refs = full_disk.path / "refs"
    refused_on_full_disk(capsys, full_disk, ["refs", "regenerate", "balls", *own_options(own_project, refs)])


# --- the writers themselves ---------------------------------------------------------------------


def test_every_writer_raises_one_error_and_keeps_the_old_file(full_disk):
    from wrt.files import write_atomic, write_json
    from wrt.imageio import write_image, write_srgb_png

    rgb = np.random.default_rng(1).random((96, 128, 3)).astype(np.float32)
    old = {
        "a.exr": lambda p: write_image(p, rgb),
        "a.png": lambda p: write_image(p, rgb),
        "s.png": lambda p: write_srgb_png(p, (255 * rgb).astype(np.uint8)),
        "a.json": lambda p: write_json(p, {"values": rgb[:8].tolist()}),
        "a.txt": lambda p: write_atomic(p, "x" * 20000),
    }
    for name, write in old.items():
        write(full_disk.path / name)
    before = snapshot(full_disk.path)
    full_disk.fill()
    for name, write in old.items():
        with pytest.raises(WrtError, match=name.replace(".", r"\.")):
            write(full_disk.path / name)
    assert snapshot(full_disk.path) == before
    assert entries(full_disk.path) == set(before)


def test_a_report_folder_on_a_full_disk_keeps_the_old_report(full_disk):
    from wrt.files import report_folder, write_atomic

    folder = full_disk.path / "report"
    with report_folder(folder, "test") as work:
        write_atomic(Path(work) / "index.html", "old")
    before = snapshot(full_disk.path)
    full_disk.fill()
    with pytest.raises(WrtError), report_folder(folder, "test") as work:
        write_atomic(Path(work) / "index.html", "new" * 10000)
    assert snapshot(full_disk.path) == before
    assert entries(full_disk.path) == {str(Path(p).parent) for p in before if "/" in p} | set(before)


def test_the_stress_report_on_a_full_disk_keeps_the_old_one(full_disk):
    from wrt.stress.report import CaseResult, write_report

    results = [CaseResult(case="c", rays=10, failures=0, worst=0.0, bound=1.0, unit="", seconds=0.1)]
    write_report(results, str(full_disk.path / "stress"), 10, 0)
    before = snapshot(full_disk.path)
    full_disk.fill()
    with pytest.raises(WrtError):
        write_report(results * 200, str(full_disk.path / "stress"), 10, 0)
    assert snapshot(full_disk.path) == before
