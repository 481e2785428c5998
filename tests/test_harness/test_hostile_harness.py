"""A hostile user against the harness's and the benchmarks' commands (issue 25): every bad input is
one line ``wrt: error: ...`` naming the file or option and exit code 2, refused before any work is
done (the work is replaced by a function that fails the test if it is reached); no file outside a
mutant's scratch copy is ever written; no input blocks; a features file imports no code but wrt's.

One test (or one parametrized group) per class, each of which failed on the code before the fix."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import sys
import threading

import pytest
import wrt_harness.commands as commands
import wrt_harness.mutants as mutants
from conftest import EXAMPLES, copy_references, one_feature_file
from test_mutants import SMOKE, fault_entry, write_faults
from wrt_benchmarks import bench
from wrt_harness.matrix import load_features, scene_path
from wrt_harness.mutants import Fault, apply_fault, package_dirs, source_file, tree_digest

from wrt.cli import main
from wrt.errors import WrtError

FEATURE = "raycast_sphere"  # wrt's own, deterministic: its references are small
DEEP_JSON = {"array": "[" * 100_000 + "]" * 100_000, "object": '{"a": ' * 100_000 + "1" + "}" * 100_000}


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("wrt: error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    return err


def not_called(what: str):
    """A stand-in for the work: reaching it means the bad input was not refused first."""

    def fail(*args, **kwargs):
        raise AssertionError(f"{what} ran: the bad input was not refused before the work")

    return fail


@pytest.fixture(scope="module")
def own_refs(tmp_path_factory):
    """A project's own features file (one 16x16 raycast feature ``x``) and its references."""
    folder = tmp_path_factory.mktemp("own")
    features = one_feature_file(folder, "")
    refs = folder / "refs"
    assert main(["refs", "regenerate", "--features", str(features), "--refs", str(refs)]) == 0
    return features, refs


def copy_own_refs(own_refs, tmp_path):
    features, refs = own_refs
    copy = tmp_path / "refs"
    shutil.copytree(refs, copy)
    return str(features), copy


# --- class 1: a faults file writes outside its scratch copy ------------------------------------


def victim_file(tmp_path) -> tuple:
    """A file outside the packages holding a fault's snippet once, and the fault's entry."""
    entry = fault_entry(expect=["raycast_sphere"])
    victim = tmp_path / "victim.py"
    victim.write_text(entry["old"] + "\n")
    return victim, entry


@pytest.mark.parametrize("form", ["dot_dot", "absolute", "dot_dot_inside"])
def test_a_fault_file_outside_the_packages_is_refused_before_anything_is_copied(tmp_path, monkeypatch, capsys, form):
    """``file = "wrt/../../victim.py"`` rewrote that file outside the scratch copy, for good."""
    victim, entry = victim_file(tmp_path)
    wrt_dir = package_dirs()["wrt"]
    entry["file"] = {
        "dot_dot": "wrt/" + os.path.relpath(victim, wrt_dir),
        "absolute": str(victim),
        "dot_dot_inside": "wrt/kernels/../device.py",  # inside, but not the name of a copied file
    }[form]
    path = write_faults(tmp_path / "faults.toml", [entry])
    monkeypatch.setattr(mutants, "copy_packages", not_called("copying the packages"))
    assert main(["mutants", "--faults", path, "--expected", "--report", str(tmp_path / "out")]) == 2
    err = one_error_line(capsys)
    assert "key 'file'" in err and SMOKE in err, err
    assert victim.read_text() == entry["old"] + "\n"


def test_applying_a_fault_never_writes_outside_the_scratch_copy(tmp_path):
    """The mechanism itself: ``apply_fault`` joined the scratch folder and ``file`` and wrote there."""
    victim, entry = victim_file(tmp_path)
    scratch = tmp_path / "scratch"
    (scratch / "wrt").mkdir(parents=True)
    fault = Fault(**{**entry, "file": "wrt/../../victim.py", "expect": ("raycast_sphere",)})
    with pytest.raises(WrtError, match="key 'file'"):
        apply_fault(fault, str(scratch))
    assert victim.read_text() == entry["old"] + "\n"


@pytest.mark.parametrize("link", ["file", "folder"])
def test_a_fault_file_through_a_symbolic_link_is_refused(tmp_path, link):
    """A package file or folder that is a link out of the package is not a file of the package."""
    victim, entry = victim_file(tmp_path)
    package = tmp_path / "pkg" / "wrt"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    if link == "file":
        (package / "evil.py").symlink_to(victim)
        name = "wrt/evil.py"
    else:
        (package / "sub").symlink_to(tmp_path, target_is_directory=True)
        name = "wrt/sub/victim.py"
    fault = Fault(**{**entry, "file": name, "expect": ("raycast_sphere",)})
    with pytest.raises(WrtError, match="key 'file'"):
        source_file(fault, {"wrt": str(package)})


# --- class 2: tracebacks, or refusals after the work -------------------------------------------


@pytest.mark.parametrize("verb", ["regenerate", "calibrate"])
def test_a_read_only_refs_folder_is_refused_before_rendering(own_refs, read_only_folder, monkeypatch, capsys, verb):
    features, refs = own_refs
    ro = read_only_folder({p.name: p.read_bytes() for p in refs.iterdir()})
    monkeypatch.setattr(commands, "render_reference", not_called("the reference render"))
    monkeypatch.setattr(commands, "calibrate", not_called("the calibration renders"))
    assert main(["refs", verb, "--features", str(features), "--refs", str(ro)]) == 2
    err = one_error_line(capsys)
    assert f"--refs {ro}" in err and "not writable" in err, err


@pytest.mark.parametrize("verb, ext", [("regenerate", "exr"), ("regenerate", "png"), ("calibrate", "json")])
def test_a_reference_path_that_is_a_folder_is_refused_before_rendering(
    own_refs, tmp_path, monkeypatch, capsys, verb, ext
):
    features, refs = copy_own_refs(own_refs, tmp_path)
    (refs / f"x.{ext}").unlink()
    (refs / f"x.{ext}").mkdir()
    monkeypatch.setattr(commands, "render_reference", not_called("the reference render"))
    monkeypatch.setattr(commands, "calibrate", not_called("the calibration renders"))
    assert main(["refs", verb, "--features", features, "--refs", str(refs)]) == 2
    err = one_error_line(capsys)
    assert str(refs / f"x.{ext}") in err and "is a folder" in err, err


@pytest.mark.parametrize("depth", DEEP_JSON)
def test_a_calibration_nested_too_deeply_is_one_line(tmp_path, monkeypatch, capsys, depth):
    """json.load's RecursionError was a traceback."""
    folder = copy_references(tmp_path, monkeypatch, [FEATURE])
    (folder / f"{FEATURE}.json").write_text(DEEP_JSON[depth])
    assert main(["matrix", FEATURE]) == 2
    err = one_error_line(capsys)
    assert str(folder / f"{FEATURE}.json") in err and "nested too deeply" in err, err
    assert f"wrt refs calibrate {FEATURE}" in err, err


def stored_result(**changes) -> dict:
    """A well-formed ``mutants.json`` entry for wrt's fault ``SMOKE`` in --expected mode on this tree
    (so that it is taken as measured before), with ``changes``."""
    fault = Fault(**{**fault_entry(expect=["raycast_sphere"]), "expect": ("raycast_sphere",)})
    result = {
        "features": {
            "raycast_sphere": {"passed": False, "failed_checks": ["geometry"], "failures": ["x"], "scores": {}}
        },
        "crashed": None,
        "caught_by": {"raycast_sphere": ["geometry"]},
        "caught": True,
        "expected_caught": True,
        "checks": ["geometry"],
        "fault": fault.digest(),
        "tree": tree_digest(package_dirs()),
        "mode": "expected",
        "args": ["--jobs", "1", "--device", "cpu"],
        "time_s": 5.0,
    }
    return {**result, **changes}


MUTANTS_JSON = {
    "deep_array": (DEEP_JSON["array"], "nested too deeply"),
    "deep_object": (DEEP_JSON["object"], "nested too deeply"),
    "a_list": ("[1, 2]", "not an object"),
    "no_faults": ('{"machine": {}}', "faults: missing"),
    "faults_a_list": ('{"faults": [1, 2]}', "faults: must be an object"),
    "result_a_number": (json.dumps({"faults": {SMOKE: 5}}), f"faults.{SMOKE}"),
    "result_missing_keys": (json.dumps({"faults": {SMOKE: {"fault": "abc"}}}), f"faults.{SMOKE}"),
    "caught_by_a_list": (None, "caught_by"),
    "checks_of_numbers": (None, "checks"),
    "crashed_a_number": (None, "crashed"),
}


@pytest.mark.parametrize("shape", MUTANTS_JSON, ids=list(MUTANTS_JSON))
def test_a_mutants_json_of_the_wrong_shape_is_one_line(tmp_path, monkeypatch, capsys, shape):
    """A list where an object belongs, a missing key, a result of the wrong type: tracebacks."""
    text, key = MUTANTS_JSON[shape]
    if text is None:
        bad = {
            "caught_by_a_list": {"caught_by": [1]},
            "checks_of_numbers": {"checks": [1, 2]},
            "crashed_a_number": {"crashed": 3},
        }[shape]
        text = json.dumps({"faults": {SMOKE: stored_result(**bad)}})
    path = write_faults(tmp_path / "faults.toml", [fault_entry(expect=["raycast_sphere"])])
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "mutants.json").write_text(text)
    monkeypatch.setattr(mutants, "copy_packages", not_called("copying the packages"))
    assert main(["mutants", "--faults", path, "--expected", "--report", str(tmp_path / "out")]) == 2
    err = one_error_line(capsys)
    assert "mutants.json: not the results of wrt mutants" in err and key in err, err


def test_a_well_formed_mutants_json_is_resumed(tmp_path, monkeypatch, capsys):
    """The shape check accepts what ``wrt mutants`` writes (its committed results included)."""
    path = write_faults(tmp_path / "faults.toml", [fault_entry(expect=["raycast_sphere"])])
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "mutants.json").write_text(json.dumps({"machine": {}, "faults": {SMOKE: stored_result()}}))
    monkeypatch.setattr(mutants, "copy_packages", not_called("copying the packages"))
    assert main(["mutants", "--faults", path, "--expected", "--report", str(tmp_path / "out")]) == 0
    assert "measured before" in capsys.readouterr().out
    committed = os.path.join(os.path.dirname(mutants.__file__), "..", "benchmarks", "results", "mutants.json")
    if os.path.exists(committed):
        mutants.load_results(committed)


def test_a_matrix_json_of_the_wrong_shape_counts_as_a_crashed_run(tmp_path, monkeypatch):
    """The mutant run's own ``--json`` output is checked too: a malformed one is a crashed run."""

    def fake_run(command, scratch, env):
        with open(command[-1], "w") as f:
            f.write('{"features": [1, 2]}')
        return 0, ""

    monkeypatch.setattr(mutants, "_run_to_end", fake_run)
    run = mutants.run_matrix_copy(str(tmp_path), {}, ["raycast_sphere"], [])
    assert "crashed" in run and "features" in run["crashed"], run


def test_matrix_json_is_checked_before_the_work(tmp_path, monkeypatch, capsys, read_only_folder, own_refs):
    copy_references(tmp_path, monkeypatch, [FEATURE])
    monkeypatch.setattr(commands, "run_matrix", not_called("the matrix"))
    ro = read_only_folder()
    for target, problem in ((ro / "m.json", "not writable"), (tmp_path, "is a folder")):
        assert main(["matrix", FEATURE, "--json", str(target)]) == 2
        err = one_error_line(capsys)
        assert f"--json {target}" in err and problem in err, err
    features, refs = own_refs  # nor may it replace the features file it reads
    assert main(["matrix", "--features", str(features), "--refs", str(refs), "--json", str(features)]) == 2
    err = one_error_line(capsys)
    assert f"--json {features}" in err and "input" in err, err


def test_matrix_report_is_checked_before_the_work(tmp_path, monkeypatch, capsys, read_only_folder):
    copy_references(tmp_path, monkeypatch, [FEATURE])
    monkeypatch.setattr(commands, "run_matrix", not_called("the matrix"))
    notes = tmp_path / "notes"
    notes.mkdir()
    (notes / "mine.txt").write_text("the user's own file")
    for target in (read_only_folder() / "report", notes, notes / "mine.txt"):
        assert main(["matrix", FEATURE, "--report", str(target)]) == 2
        assert f"--report {target}" in one_error_line(capsys)
    assert (notes / "mine.txt").read_text() == "the user's own file"


def test_false_alarms_json_is_checked_before_the_work(tmp_path, monkeypatch, capsys, read_only_folder):
    stochastic = next(f.name for f in load_features() if f.stochastic)
    copy_references(tmp_path, monkeypatch, [stochastic])
    monkeypatch.setattr(commands, "false_alarms", not_called("the false-alarm renders"))
    target = read_only_folder() / "fa.json"
    assert main(["refs", "false-alarms", stochastic, "--seeds", "1", "--json", str(target)]) == 2
    err = one_error_line(capsys)
    assert f"--json {target}" in err and "not writable" in err, err


def output_folder(tmp_path, read_only_folder, where: str, results: str):
    """An output folder a command must refuse, by ``where``: a file (the user's own, ``a_file``),
    a folder under it, a read-only folder or one under it, or a folder whose ``results`` file is a
    folder."""
    (tmp_path / "a_file").write_text("the user's own file")
    if where == "results_a_folder":
        (tmp_path / "out" / results).mkdir(parents=True)
    if where in ("read_only", "under_read_only"):
        return read_only_folder() / ("out" if where == "under_read_only" else "")
    return {
        "a_file": tmp_path / "a_file",
        "under_a_file": tmp_path / "a_file" / "out",
        "results_a_folder": tmp_path / "out",
    }[where]


@pytest.mark.parametrize("where", ["a_file", "under_a_file", "read_only", "under_read_only", "results_a_folder"])
def test_mutants_report_is_checked_before_the_work(tmp_path, monkeypatch, capsys, read_only_folder, where):
    path = write_faults(tmp_path / "faults.toml", [fault_entry(expect=["raycast_sphere"])])
    report = output_folder(tmp_path, read_only_folder, where, "mutants.json")
    monkeypatch.setattr(mutants, "copy_packages", not_called("copying the packages"))
    assert main(["mutants", "--faults", path, "--expected", "--report", str(report)]) == 2
    assert "--report" in one_error_line(capsys)
    assert (tmp_path / "a_file").read_text() == "the user's own file"


def test_mutants_kernel_cache_is_checked_before_the_work(tmp_path, monkeypatch, capsys):
    """A kernel cache Warp cannot write crashed every mutant run, and a crashed run counts as caught."""
    path = write_faults(tmp_path / "faults.toml", [fault_entry(expect=["raycast_sphere"])])
    (tmp_path / "a_file").write_text("the user's own file")
    monkeypatch.setattr(mutants, "copy_packages", not_called("copying the packages"))
    argv = ["mutants", "--faults", path, "--expected", "--report", str(tmp_path / "out")]
    assert main([*argv, "--kernel-cache", str(tmp_path / "a_file")]) == 2
    assert f"--kernel-cache {tmp_path / 'a_file'}: is a file" in one_error_line(capsys)


@pytest.mark.parametrize("where", ["a_file", "under_a_file", "read_only", "under_read_only", "results_a_folder"])
def test_bench_output_folder_is_checked_before_the_work(tmp_path, monkeypatch, capsys, read_only_folder, where):
    """``wrt bench -o FILE`` ended in a NotADirectoryError traceback after the warm-up renders."""
    out = output_folder(tmp_path, read_only_folder, where, "results.json")
    monkeypatch.setattr(bench, "run", not_called("the benchmark"))
    scene = str(EXAMPLES / "path" / "soft_shadows.toml")
    assert main(["bench", scene, "--quick", "--triangles", "0", "-o", str(out)]) == 2
    assert f"-o {out}" in one_error_line(capsys)
    assert (tmp_path / "a_file").read_text() == "the user's own file"


# --- class 3: reads that block or never end ----------------------------------------------------


@pytest.mark.parametrize("option", ["--features", "--faults"])
def test_a_device_as_features_or_faults_file_is_refused(tmp_path, capsys, option):
    """``--features /dev/zero`` read until memory ran out; /dev/null (safe to try on the old code)
    was read as an empty file."""
    if option == "--features":
        argv = ["matrix", "--features", "/dev/null", "--refs", str(tmp_path)]
    else:
        argv = ["mutants", "--faults", "/dev/null", "--report", str(tmp_path / "out")]
    assert main(argv) == 2
    err = one_error_line(capsys)
    assert "/dev/null" in err and "device" in err, err
    assert main([*argv[:2], "/dev/zero", *argv[3:]]) == 2
    assert "/dev/zero" in one_error_line(capsys)


def test_a_fifo_as_features_file_is_refused_without_blocking(tmp_path, capsys):
    """A FIFO blocked the read until a writer came (here a thread writes, so that the old code
    ended: with a message that did not say what the file is)."""
    fifo = tmp_path / "features.toml"
    os.mkfifo(fifo)

    def feed():
        with contextlib.suppress(OSError), open(fifo, "wb") as f:
            f.write(b"x = 1\n")

    feeder = threading.Thread(target=feed, daemon=True)
    feeder.start()
    try:
        assert main(["matrix", "--features", str(fifo), "--refs", str(tmp_path)]) == 2
        err = one_error_line(capsys)
        assert str(fifo) in err and "FIFO" in err, err
    finally:
        with contextlib.suppress(OSError):  # a reader for a moment: the feeder's open returns
            os.close(os.open(fifo, os.O_RDONLY | os.O_NONBLOCK))
        feeder.join(5)


@pytest.mark.parametrize(
    "content, problem",
    [
        (b"x = " + b"[" * 100_000 + b"]" * 100_000, "nested too deeply"),
        (b"\xff\xfe[[feature]]", "not UTF-8"),
        (b"x = " + b"9" * 5000, "too many digits"),
    ],
    ids=["deep", "not_utf8", "huge_integer"],
)
def test_a_features_file_nested_too_deeply_or_not_toml_is_one_line(tmp_path, capsys, content, problem):
    features = tmp_path / "features.toml"
    features.write_bytes(content)
    assert main(["matrix", "--features", str(features), "--refs", str(tmp_path)]) == 2
    err = one_error_line(capsys)
    assert str(features) in err and problem in err, err


# --- class 4: a features file imports code -----------------------------------------------------


def test_package_scene_of_another_package_is_refused_without_importing_it(tmp_path, monkeypatch, capsys):
    """``scene = "this:x.toml"`` imported ``this`` (which prints the Zen of Python) to find its folder."""
    monkeypatch.delitem(sys.modules, "this", raising=False)
    features = tmp_path / "features.toml"
    features.write_text(
        '[[feature]]\nname = "x"\nscene = "this:x.toml"\nintegrator = "raycast"\nwidth = 16\nheight = 16\n'
    )
    with pytest.raises(WrtError) as e:
        load_features(str(features))
    assert "this:x.toml" in str(e.value) and "wrt's own" in str(e.value) and str(features) in str(e.value)
    assert "this" not in sys.modules and "Beautiful is better" not in capsys.readouterr().out


def test_a_package_that_runs_code_on_import_is_never_imported(tmp_path, monkeypatch, capsys):
    """A package whose import has side effects (here: a marker file, then an exception: a traceback)."""
    site = tmp_path / "site"
    (site / "evil_pkg").mkdir(parents=True)
    marker = tmp_path / "imported"
    (site / "evil_pkg" / "__init__.py").write_text(f"open({str(marker)!r}, 'w').close()\nraise RuntimeError('boom')\n")
    monkeypatch.syspath_prepend(str(site))
    features = tmp_path / "features.toml"
    features.write_text(
        '[[feature]]\nname = "x"\nscene = "evil_pkg:x.toml"\nintegrator = "raycast"\nwidth = 16\nheight = 16\n'
    )
    assert main(["matrix", "--features", str(features), "--refs", str(tmp_path)]) == 2
    assert "evil_pkg" in one_error_line(capsys)
    assert not marker.exists()


@pytest.mark.parametrize("spec", ["wrt_harness.__main__:x.toml", "wrt_harness.__main__.sub:x.toml"])
def test_a_module_of_wrt_that_is_not_a_package_is_never_imported(tmp_path, monkeypatch, spec):
    """``wrt_harness.__main__`` runs the harness's command when imported."""
    monkeypatch.delitem(sys.modules, "wrt_harness.__main__", raising=False)
    with pytest.raises(WrtError, match="not a package"):
        scene_path(spec, str(tmp_path))
    assert "wrt_harness.__main__" not in sys.modules


def test_wrt_own_packages_still_resolve(tmp_path):
    assert scene_path("wrt.examples:raycast/raycast_sphere.toml", str(tmp_path)) == str(
        EXAMPLES / "raycast" / "raycast_sphere.toml"
    )
    assert os.path.isfile(scene_path("wrt_harness:features.toml", str(tmp_path)))
    assert scene_path("scenes/a.toml", str(tmp_path)) == str(tmp_path / "scenes" / "a.toml")


# --- class 5: --device -------------------------------------------------------------------------


@pytest.mark.parametrize(
    "argv",
    [
        ["matrix", "no_such_feature"],
        ["refs", "regenerate", "no_such_feature"],
        ["refs", "calibrate", "no_such_feature"],
        ["refs", "false-alarms", "no_such_feature"],
        ["mutants", "no_such_fault"],
        ["bench", "no/such/scene.toml"],
    ],
    ids=lambda argv: " ".join(argv[:2]),
)
@pytest.mark.parametrize("device", ["", "gpu", "cuda:x"])
def test_a_bad_device_is_refused_by_every_verb(capsys, argv, device):
    """``--device ""`` was accepted (and rendered on the CPU)."""
    with pytest.raises(SystemExit) as e:
        main([*argv, "--device", device])
    assert e.value.code == 2
    err = capsys.readouterr().err  # argparse's line: "wrt VERB: error: argument --device: ..."
    assert err.startswith(f"wrt {argv[0]}") and err.count("\n") == 1 and "Traceback" not in err, err
    assert "error: argument --device" in err and repr(device) in err, err
