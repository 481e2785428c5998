"""A project's own matrix (``--features FILE --refs DIR``): the example project
``examples/own_matrix`` run as its README runs it (regenerate, calibrate, matrix with a report,
the wrong variants), from another folder than its own, and its bad input refused (exit code 2)."""

import os
import re
import shlex
import shutil
from pathlib import Path

import pytest
import wrt_harness.references as references

from wrt.cli import main

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "own_matrix"
NAMES = ("balls", "shadow", "lamp")
OPTIONS = ["--features", "own/features.toml", "--refs", "own/refs"]


@pytest.fixture
def project(tmp_path, monkeypatch):
    """A copy of the example project at ``tmp_path/own``, the working folder ``tmp_path``: the
    features file's scene paths must resolve against its own folder, not the working folder."""
    shutil.copytree(EXAMPLE, tmp_path / "own", ignore=shutil.ignore_patterns("refs", "report"))
    monkeypatch.chdir(tmp_path)
    return tmp_path / "own"


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("wrt: error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    return err


def test_the_example_project_runs_its_own_matrix(project, capsys):
    assert main(["refs", "regenerate", *OPTIONS]) == 0
    out = capsys.readouterr().out
    for name in NAMES:
        assert re.search(rf"^{name}: \d+ spp, new reference; SSIM threshold 0\.\d+ \(calibrated\)$", out, re.M), out
    assert sorted(os.listdir(project / "refs")) == sorted(f"{n}.{ext}" for n in NAMES for ext in ("exr", "json", "png"))
    assert not any(os.path.exists(p) for n in NAMES for p in references.paths(n).values())  # wrt's own untouched

    assert main(["refs", "calibrate", *OPTIONS]) == 0
    assert re.search(
        r"^lamp: SSIM 0\.\d+\.\.0\.\d+ over seeds \[11, 12, 13, 14, 15, 16\]", capsys.readouterr().out, re.M
    )

    assert main(["matrix", *OPTIONS, "--report", "report"]) == 0
    out = capsys.readouterr().out
    assert "3 passed, 0 failed" in out, out
    page = (project.parent / "report" / "index.html").read_text()
    assert "wrt feature matrix: 3 of 3 pass" in page
    assert re.findall(r'<tr class="(pass|fail)" id="(\w+)"', page) == [("pass", n) for n in NAMES]

    # the harness's sensitivity: every wrong variant fails; one that changes nothing is missed (exit 1)
    assert main(["matrix", *OPTIONS, "--wrong"]) == 0
    assert "3 wrong variants caught, 0 missed" in capsys.readouterr().out
    features = project / "features.toml"
    features.write_text(features.read_text().replace("[0.98, -0.4, 0.6]", "[0.9, -0.4, 0.6]"))  # not moved
    assert main(["matrix", *OPTIONS, "--wrong", "balls"]) == 1
    assert "0 wrong variants caught, 1 missed: balls" in capsys.readouterr().out

    # a changed scene: the error names the command that fixes it, and that command does
    scene = project / "scenes" / "balls.toml"
    scene.write_text(scene.read_text().replace("radius = 0.4", "radius = 0.45"))
    assert main(["matrix", *OPTIONS]) == 2
    err = one_error_line(capsys)
    fix = "wrt refs regenerate --features own/features.toml --refs own/refs balls"
    assert "scene hash differs" in err and err.rstrip().endswith(f"run: {fix}"), err
    assert main(shlex.split(fix)[1:]) == 0
    assert main(["matrix", *OPTIONS, "balls"]) == 0


def bad_features(project, old, new):
    path = project / "features.toml"
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new))


BAD_INPUT = {
    "missing_file": (
        ["--features", "own/nothing.toml", "--refs", "own/refs"],
        None,
        ["own/nothing.toml", "cannot read"],
    ),
    "not_toml": (OPTIONS, ('name = "balls"', 'name = "balls'), ["own/features.toml", "not valid TOML"]),
    "no_features": (OPTIONS, ("[[feature]]", "[[features]]"), ["own/features.toml", "no [[feature]] tables"]),
    "integrator": (
        OPTIONS,
        ('integrator = "path"', 'integrator = "paths"'),
        ["own/features.toml: feature[2].integrator = 'paths'", "raycast, whitted, path"],
    ),
    "scene_file": (
        OPTIONS,
        ('"scenes/shadow.toml"', '"scenes/shadows.toml"'),
        ["feature[1].scene = 'scenes/shadows.toml': no such file", str(Path("own", "scenes", "shadows.toml"))],
    ),
    "unknown_key": (OPTIONS, ("spp = 4", "spps = 4"), ["feature[1]: unknown key 'spps'"]),
    "missing_key": (OPTIONS, ('integrator = "raycast"\n', ""), ["feature[0]: missing key 'integrator'"]),
    "name": (OPTIONS, ('name = "balls"', 'name = "../balls"'), ["feature[0].name = '../balls'", "names files"]),
    "wrong_variant": (
        OPTIONS,
        ('wrong = { description = "the light moved left by 0.5", set', 'wrong = { description = "x", sets'),
        ["feature[1].wrong = ", "description and set"],
    ),
    "no_refs_option": (["--features", "own/features.toml"], None, ["--features own/features.toml", "--refs DIR"]),
    "no_refs_folder": (
        ["--features", "own/features.toml", "--refs", "own/nowhere"],
        None,
        ["--refs own/nowhere: no such folder", "wrt refs regenerate --features own/features.toml --refs own/nowhere"],
    ),
}


@pytest.mark.parametrize("case", BAD_INPUT, ids=list(BAD_INPUT))
@pytest.mark.parametrize("verb", [["matrix"], ["refs", "calibrate"]], ids=" ".join)
def test_bad_input_is_one_line_and_exit_2(project, capsys, case, verb):
    options, change, expected = BAD_INPUT[case]
    if change:
        bad_features(project, *change)
    assert main([*verb, *options]) == 2
    err = one_error_line(capsys)
    assert all(e in err for e in expected), err
    assert not (project / "nowhere").exists()


def test_wrong_needs_a_wrong_variant(project, capsys):
    bad_features(project, 'wrong = { description = "the light moved left by 0.5"', "# ")
    assert main(["matrix", "--wrong", "--features", "own/features.toml", "--refs", "own"]) == 2
    assert "own/features.toml: feature 'shadow' has no wrong variant" in one_error_line(capsys)


def test_regenerate_makes_its_folder(project, capsys):
    assert main(["refs", "regenerate", "balls", "--features", "own/features.toml", "--refs", "own/new/refs"]) == 0
    assert sorted(os.listdir(project / "new" / "refs")) == ["balls.exr", "balls.json", "balls.png"]
    (project / "file").write_text("")
    assert main(["refs", "regenerate", "balls", "--features", "own/features.toml", "--refs", "own/file"]) == 2
    assert "--refs own/file: cannot make the folder" in one_error_line(capsys)


def test_the_readme_shows_the_features_file_as_it_is():
    """The README's features file is the project's (less its opening comment)."""
    shown = re.search(r"```toml\n(.*?)```", (EXAMPLE / "README.md").read_text(), re.S)[1]
    text = (EXAMPLE / "features.toml").read_text()
    assert shown == text[text.index("\n[[feature]]\n") + 1 :]
