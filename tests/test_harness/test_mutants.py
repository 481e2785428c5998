"""``wrt mutants`` (``harness/mutants.py``): every planted fault still applies to the tree, the
faults file is validated strictly, and one host-side fault (no kernel recompiles) runs end to end
on one small feature, is caught, and leaves the working tree untouched."""

import json

import pytest
from wrt_harness.matrix import FEATURES_FILE, load_features
from wrt_harness.mutants import check_applies, load_faults, package_dirs, source_file

from wrt.cli import main

SMOKE = "camera_fov_half_angle"  # in wrt/device.py: host code, caught by the raycast features


def write_faults(path, faults: list[dict]) -> str:
    """``faults`` as a faults file at ``path`` (TOML basic strings: JSON's escapes)."""
    text = "".join(
        "[[fault]]\n" + "".join(f"{key} = {json.dumps(value)}\n" for key, value in fault.items()) for fault in faults
    )
    path.write_text(text)
    return str(path)


def fault_entry(fault_id: str = SMOKE, **changes) -> dict:
    """The entry of wrt's own fault ``fault_id`` as a dict, with ``changes``."""
    fault = next(f for f in load_faults() if f.id == fault_id)
    entry = {**fault.__dict__, "expect": list(fault.expect)}
    return {**entry, **changes}


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("wrt: error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    return err


def test_every_fault_applies_to_the_tree_exactly_once():
    faults = load_faults()
    assert len(faults) >= 28
    dirs = package_dirs()
    for fault in faults:
        check_applies(fault, dirs)  # raises naming the fault when its snippet drifted away
    features = {f.name for f in load_features(FEATURES_FILE)}
    assert all(set(f.expect) <= features for f in faults)


@pytest.mark.parametrize(
    "change, message",
    [
        ({"drop": "expect"}, "key 'expect' missing"),
        ({"extra": "yes"}, "unknown key 'extra'"),
        ({"expect": ["no_such_feature"]}, "'no_such_feature' is not a feature"),
        ({"expect": []}, "must be a non-empty list"),
        ({"old": 3}, "key 'old' = 3: must be a non-empty string"),
        ({"file": "wrt/../device.py"}, "key 'file' = 'wrt/../device.py': must be a relative path inside"),
        ({"file": "/etc/hostname"}, "key 'file' = '/etc/hostname': must be a relative path inside"),
        ({"duplicate": True}, "key 'id' = 'camera_fov_half_angle': duplicate id"),
    ],
)
def test_a_bad_faults_file_is_one_line_and_exit_2(tmp_path, capsys, change, message):
    entry = fault_entry()
    if "drop" in change:
        del entry[change["drop"]]
    elif "duplicate" in change:
        pass
    else:
        entry.update(change)
    faults = [entry, entry] if "duplicate" in change else [entry]
    path = write_faults(tmp_path / "faults.toml", faults)
    assert main(["mutants", "--faults", path, "--report", str(tmp_path / "out")]) == 2
    err = one_error_line(capsys)
    assert path in err and message in err, err


def test_a_fault_whose_snippet_is_not_in_the_tree_is_refused(tmp_path, capsys):
    path = write_faults(tmp_path / "faults.toml", [fault_entry(old="tan_half_fov = no such code")])
    assert main(["mutants", "--faults", path, "--report", str(tmp_path / "out")]) == 2
    err = one_error_line(capsys)
    assert SMOKE in err and "wrt/device.py" in err and "tan_half_fov = no such code" in err and "0 times" in err


def test_one_host_side_fault_end_to_end(tmp_path, capsys):
    fault = fault_entry(expect=["raycast_sphere"])
    path = write_faults(tmp_path / "faults.toml", [fault])
    target = source_file(load_faults(path)[0])
    before = open(target, "rb").read()
    report = tmp_path / "out"
    assert main(["mutants", "--faults", path, "--expected", "--report", str(report)]) == 0
    out = capsys.readouterr().out
    assert out.rstrip().endswith("1 of 1 planted faults caught"), out
    assert open(target, "rb").read() == before  # the working tree is untouched
    result = json.loads((report / "mutants.json").read_text())
    r = result["faults"][SMOKE]
    assert r["caught"] and r["expected_caught"] and "raycast_sphere" in r["caught_by"], r
    assert "geometry" in r["caught_by"]["raycast_sphere"] and "machine" in result
    # measured again only when the fault or the tree changes
    assert main(["mutants", "--faults", path, "--expected", "--report", str(report)]) == 0
    assert "measured before" in capsys.readouterr().out


def test_a_crashed_matrix_run_counts_as_caught_and_says_so(tmp_path, capsys):
    fault = fault_entry(expect=["raycast_sphere"])
    fault.update(id="syntax_error", new=fault["old"] + " +")  # the mutated wrt cannot even be imported
    path = write_faults(tmp_path / "faults.toml", [fault])
    assert main(["mutants", "--faults", path, "--expected", "--report", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "the matrix run crashed" in out and "SyntaxError" in out and "1 of 1 planted faults caught" in out, out


def test_results_that_are_not_mutants_json_are_refused(tmp_path, capsys):
    path = write_faults(tmp_path / "faults.toml", [fault_entry(expect=["raycast_sphere"])])
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "mutants.json").write_text("[1, 2")
    assert main(["mutants", "--faults", path, "--report", str(tmp_path / "out")]) == 2
    assert "mutants.json: not the results of wrt mutants" in one_error_line(capsys)


# --- an interruption is not a catch -------------------------------------------------------------


def test_a_matrix_run_killed_by_a_signal_is_not_a_catch(tmp_path, capsys):
    """A run stopped from outside used to be recorded as "caught (crashed, exit -15)", and a
    resumed run then skipped the fault. Here the mutated wrt sends itself SIGTERM: no result,
    nothing recorded, exit code 2 naming the resumption."""
    fault = fault_entry(expect=["raycast_sphere"])
    fault.update(id="killed_from_outside", new=fault["old"] + "; import os, signal; os.kill(os.getpid(), 15)")
    path = write_faults(tmp_path / "faults.toml", [fault])
    report = tmp_path / "out"
    assert main(["mutants", "--faults", path, "--expected", "--report", str(report)]) == 2
    err = one_error_line(capsys)
    assert "from outside" in err and "not recorded" in err, err
    recorded = json.loads((report / "mutants.json").read_text())["faults"] if (report / "mutants.json").exists() else {}
    assert "killed_from_outside" not in recorded


def _processes_in(folder, word: bytes = b"") -> list[int]:
    """Processes whose working folder is under ``folder`` (the mutant runs work in their scratch
    copy) and whose command line holds ``word``."""
    import os

    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            if os.readlink(f"/proc/{pid}/cwd").startswith(str(folder)):
                with open(f"/proc/{pid}/cmdline", "rb") as f:
                    if word in f.read():
                        found.append(int(pid))
        except OSError:
            continue
    return found


def test_stopping_the_runner_stops_its_matrix_run_and_removes_its_scratch_copy(tmp_path):
    import os
    import signal
    import subprocess
    import sys
    import time

    path = write_faults(tmp_path / "faults.toml", [fault_entry(expect=["raycast_sphere"])])
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    report = tmp_path / "out"
    runner = subprocess.Popen(
        [sys.executable, "-m", "wrt", "mutants", "--faults", path, "--expected", "--report", str(report)],
        env={**os.environ, "TMPDIR": str(scratch)},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120
    while not _processes_in(scratch, b"matrix") and runner.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert runner.poll() is None, runner.communicate()
    runner.send_signal(signal.SIGTERM)
    out, err = runner.communicate(timeout=60)
    assert runner.returncode == 143 and "Traceback" not in err, (runner.returncode, err)
    assert _processes_in(scratch) == [], "a matrix run outlived its runner"
    assert not any(p.name.startswith("wrt-mutant-") for p in scratch.iterdir()), list(scratch.iterdir())
    assert (
        not (report / "mutants.json").exists()
        or SMOKE not in json.loads((report / "mutants.json").read_text())["faults"]
    )
