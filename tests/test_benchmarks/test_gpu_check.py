"""``benchmarks/gpu_check.sh``'s parts that need no GPU: which tests it runs, how a step's
outcome is recorded, and the report. (The whole script is dry-run with ``--device cpu --quick``.)"""

from __future__ import annotations

import sys

from wrt_benchmarks.gpu_check import agree, device_tests, report, run_step


def test_the_device_tests_are_those_parametrised_over_the_device():
    ids = ["a.py::t[cpu]", "a.py::t[cuda]", "a.py::u[2-cuda]", "a.py::u[cuda-3]", "a.py::v[cudax]", "a.py::cuda_w"]
    assert device_tests(ids, "cuda:0") == ["a.py::t[cuda]", "a.py::u[2-cuda]", "a.py::u[cuda-3]"]
    assert device_tests(ids, "cpu") == ["a.py::t[cpu]"]


def test_a_step_records_pass_failure_and_time_out(tmp_path):
    python = [sys.executable, "-c"]
    ok = run_step("matrix", [*python, "print('3 passed, 0 failed')"], 30, str(tmp_path))
    assert ok["status"] == "pass" and ok["summary"] == "3 passed, 0 failed"
    assert (tmp_path / "matrix.log").read_text() == "3 passed, 0 failed\n"
    failed = run_step("tests", [*python, "import sys; print('1 failed, 2 passed'); sys.exit(1)"], 30, str(tmp_path))
    assert failed["status"] == "FAIL (exit 1)" and failed["summary"] == "1 failed, 2 passed"
    slow = run_step("path", [*python, "import time; print('begun', flush=True); time.sleep(30)"], 1, str(tmp_path))
    assert slow["status"] == "timed out (1 s)" and slow["tail"] == ["begun"]
    assert ok["compiled"] == "0"
    announced = "print('wrt: compiled wrt_path_all_cuda for cuda:0 in 12.5 s (cached from now on)');"
    announced += "print('wrt: compiled wrt.kernels.stress for cuda:0 in 7.0 s (cached from now on)')"
    compiling = run_step("agreement", [*python, announced], 30, str(tmp_path))
    assert compiling["compiled"] == "2, 20 s"  # what the shipped PTX should have spared
    text = report("cpu", True, [ok, failed, slow, compiling], None, 2.0)
    assert "| agreement | pass | " in text and "| 2, 20 s |" in text
    assert "| matrix | pass |" in text and "## tests: FAIL (exit 1)" in text and "## path: timed out (1 s)" in text


def test_agreement_of_a_device_with_itself(tmp_path, capsys):
    assert agree(["raycast_sphere"], "cpu", str(tmp_path / "agreement.json")) == 0
    assert "1 of 1 entries agree" in capsys.readouterr().out
