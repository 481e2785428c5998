"""Planted faults (``wrt mutants``): how sensitive the matrix is to regressions in the renderer's code.

Each fault of ``faults.toml`` is a small, physically wrong code change (``old`` snippet replaced by
``new`` in one file of the installed packages). For each, the installed ``wrt`` and ``wrt_harness``
are copied to a scratch folder, the change is made there (never in the working tree), and the matrix
runs on the copy in a subprocess (``python -m wrt matrix --json``, ``PYTHONPATH`` the scratch
folder, which must win over an editable install: checked). A fault is caught when a feature fails
(by any check of ``run.CHECKS``), or when the matrix run itself crashes.

Results go to ``DIR/mutants.json`` after each fault, keyed by the fault's text and a hash of the
source tree: a fault measured there before, for the same text, tree and mode, is not run again.
Mutant runs share one Warp kernel cache (default: Warp's own, where ordinary runs have compiled the
unmutated kernels; a mutated module compiles once per variant and stays cached), so a fault costs
its matrix run plus the compilation of the modules it changes.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass

from wrt.errors import WrtError
from wrt.files import check_output_folder, read_bytes, read_json, read_toml, write_json

from .matrix import FEATURES_FILE, load_features
from .references import json_kind
from .run import CHECKS

FAULTS_FILE = os.path.join(os.path.dirname(__file__), "faults.toml")
# the installed packages a matrix run imports (pyproject.toml's packages, less the benchmarks);
# in an editable install they live in separate folders, in a wheel inside one another
PACKAGES = (
    "wrt",
    "wrt.kernels",
    "wrt.examples",
    "wrt.mitsuba",
    "wrt.stress",
    "wrt_harness",
    "wrt_harness.reference_images",
)
FAULT_KEYS = ("id", "file", "old", "new", "description", "category", "expect")
MODES = ("full", "expected", "first-catch")
CRASH = "run crashed"  # the check named for a matrix run that crashed as a whole
TAIL = 2000  # characters of a crashed run's output kept
RESULTS = "mutants.json"  # the results file in the --report folder
RESULTS_LIMIT = 256 << 20  # bytes of a results file read (all 39 faults on the full matrix: about 2 MB)


@dataclass(frozen=True)
class Fault:
    """One planted fault: in the installed file ``file`` (``wrt/kernels/materials/diffuse.py``), the snippet
    ``old`` (exactly once there) becomes ``new``; ``expect``: the features that should catch it."""

    id: str
    file: str
    old: str
    new: str
    description: str
    category: str
    expect: tuple[str, ...]

    def digest(self) -> str:
        """A hash of the fault's text: a changed fault is measured again."""
        return hashlib.sha256(json.dumps(asdict(self), sort_keys=True).encode()).hexdigest()[:16]


def load_faults(path: str = FAULTS_FILE, features_file: str | None = None) -> list[Fault]:
    """The faults of ``path``, validated strictly: every key of ``FAULT_KEYS`` and no other, strings
    (``expect`` a non-empty list of them), unique ids, ``expect`` naming features of ``features_file``
    (default: wrt's own). ``WrtError`` (one line, naming file, fault and key) otherwise."""
    doc = read_toml(path, "faults")
    entries = doc.get("fault")
    if not isinstance(entries, list) or not entries or not all(isinstance(e, dict) for e in entries):
        raise WrtError(f"{path}: needs a list of [[fault]] tables")
    features = {f.name for f in load_features(features_file or FEATURES_FILE)}
    faults, seen = [], set()
    for k, entry in enumerate(entries):
        where = f"{path}: fault {entry.get('id', k)!r}"
        for key in FAULT_KEYS:
            if key not in entry:
                raise WrtError(f"{where}: key {key!r} missing")
        for key in entry:
            if key not in FAULT_KEYS:
                raise WrtError(f"{where}: unknown key {key!r} (known: {', '.join(FAULT_KEYS)})")
        for key in FAULT_KEYS[:-1]:
            if not isinstance(entry[key], str) or not entry[key]:
                raise WrtError(f"{where}: key {key!r} = {entry[key]!r}: must be a non-empty string")
        problem = _path_problem(entry["file"])
        if problem:
            raise WrtError(f"{where}: key 'file' = {entry['file']!r}: {problem}")
        expect = entry["expect"]
        if not isinstance(expect, list) or not expect or not all(isinstance(e, str) for e in expect):
            raise WrtError(f"{where}: key 'expect' = {expect!r}: must be a non-empty list of feature names")
        for name in expect:
            if name not in features:
                raise WrtError(f"{where}: key 'expect': {name!r} is not a feature of {features_file or FEATURES_FILE}")
        if entry["id"] in seen:
            raise WrtError(f"{where}: key 'id' = {entry['id']!r}: duplicate id")
        if entry["old"] == entry["new"]:
            raise WrtError(f"{where}: key 'new': the same as 'old' (no change)")
        seen.add(entry["id"])
        faults.append(Fault(**{**entry, "expect": tuple(expect)}))
    return faults


def package_dirs() -> dict[str, str]:
    """The folder of each of ``PACKAGES`` as installed (an editable install or a wheel)."""
    dirs = {}
    for name in PACKAGES:
        spec = importlib.util.find_spec(name)
        if spec is None or not spec.submodule_search_locations:
            raise WrtError(f"package {name} is not installed: cannot copy it for mutant runs")
        dirs[name] = os.path.realpath(list(spec.submodule_search_locations)[0])
    return dirs


def _path_problem(file: str) -> str | None:
    """Why ``file`` is not the form of a path inside the installed packages, or None: it must be
    relative, '/'-separated, with no empty, '.' or '..' part (it is joined to the scratch copy)."""
    parts = file.split("/")
    if file.startswith("/") or "\\" in file or any(part in ("", ".", "..") for part in parts):
        return "must be a relative path inside the installed packages ('/'-separated, no '..', '.' or empty part)"
    return None


def source_file(fault: Fault, dirs: dict[str, str] | None = None) -> str:
    """Where the file of ``fault`` (a path inside the installed packages) lies in this installation:
    one of the files that ``copy_packages`` copies (``_files``), a regular file and no symbolic link
    out of its package, else ``WrtError`` naming the fault and the key. So a fault's path can only
    ever name a file of the scratch copy."""
    dirs = dirs or package_dirs()
    problem = _path_problem(fault.file)
    path = None if problem else dict(_files(dirs)).get(fault.file)
    if path is None:
        problem = problem or f"not a file of the packages {', '.join(sorted(dirs))}"
    elif os.path.islink(path) or not os.path.isfile(path):
        problem = f"{path} is a symbolic link or not a regular file"
    if problem:
        raise WrtError(f"fault {fault.id!r}: key 'file' = {fault.file!r}: {problem}")
    return path


def _read_source(fault: Fault, path: str) -> str:
    """The text of the fault's file at ``path``; ``WrtError`` naming the fault when it is not text."""
    data = read_bytes(path, "source")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise WrtError(f"fault {fault.id!r}: key 'file' = {fault.file!r}: {path} is not UTF-8 text") from None


def check_applies(fault: Fault, dirs: dict[str, str] | None = None) -> None:
    """``WrtError`` unless the snippet ``old`` of ``fault`` occurs exactly once in its file."""
    count = _read_source(fault, source_file(fault, dirs)).count(fault.old)
    if count != 1:
        raise WrtError(
            f"fault {fault.id!r}: key 'old' occurs {count} times in {fault.file} (must be exactly once): {fault.old!r}"
        )


def _files(dirs: dict[str, str]):
    """``(path inside the installed packages, file on disk)`` of every file of the packages, sorted."""
    for name, folder in sorted(dirs.items()):
        for root, subdirs, files in os.walk(folder):
            subdirs[:] = sorted(d for d in subdirs if d != "__pycache__")
            for file in sorted(files):
                rel = os.path.relpath(os.path.join(root, file), folder)
                yield os.path.join(*name.split("."), rel), os.path.join(root, file)


def tree_digest(dirs: dict[str, str]) -> str:
    """A hash of every file of the installed packages: results of another tree are measured again."""
    h = hashlib.sha256()
    for rel, path in _files(dirs):
        h.update(rel.encode() + b"\0")
        with open(path, "rb") as f:
            h.update(hashlib.sha256(f.read()).digest())
    return h.hexdigest()[:16]


def copy_packages(dirs: dict[str, str], dest: str) -> None:
    """Copy the installed packages to ``dest`` as a wheel lays them out (``dest/wrt/kernels/...``)."""
    for rel, path in _files(dirs):
        target = os.path.join(dest, rel)
        if not os.path.exists(target):  # a wheel's subpackage was copied with its parent
            os.makedirs(os.path.dirname(target), exist_ok=True)
            shutil.copy2(path, target)


def apply_fault(fault: Fault, scratch: str) -> None:
    """Make the change of ``fault`` in the scratch copy ``scratch``: only ever in a regular file
    inside it (``WrtError`` naming the fault otherwise; ``source_file`` has checked the path)."""
    root = os.path.realpath(scratch)
    problem = _path_problem(fault.file)
    path = os.path.join(root, *fault.file.split("/"))
    if not problem and not (
        os.path.realpath(path).startswith(root + os.sep) and os.path.isfile(path) and not os.path.islink(path)
    ):
        problem = "not a file of the scratch copy"
    if problem:
        raise WrtError(f"fault {fault.id!r}: key 'file' = {fault.file!r}: {problem}")
    text = _read_source(fault, path)
    if text.count(fault.old) != 1:
        raise WrtError(f"fault {fault.id!r}: key 'old' does not occur exactly once in the copy of {fault.file}")
    with open(path, "w", encoding="utf-8") as f:
        f.write(text.replace(fault.old, fault.new))


def _environment(scratch: str, kernel_cache: str | None) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([scratch] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    if kernel_cache:
        env["WARP_CACHE_PATH"] = os.path.abspath(kernel_cache)  # the run's working folder is the scratch copy
    return env


def check_imports(scratch: str, env: dict[str, str]) -> None:
    """``WrtError`` unless a Python started as the mutant runs are imports every package from ``scratch``."""
    imports = "{n: importlib.import_module(n).__path__[0] for n in %s}" % (PACKAGES,)
    code = f"import importlib, json; print(json.dumps({imports}))"
    out = subprocess.run([sys.executable, "-c", code], cwd=scratch, env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise WrtError(f"mutant runs cannot import the scratch copy: {out.stderr.strip()[-TAIL:]}")
    root = os.path.realpath(scratch)
    for name, path in json.loads(out.stdout).items():
        if not os.path.realpath(path).startswith(root + os.sep):
            raise WrtError(f"mutant runs import {name} from {path}, not from the scratch copy {scratch}")


INTERRUPTIONS = {
    -signal.SIGINT,
    -signal.SIGTERM,
    -signal.SIGHUP,
    -signal.SIGKILL,
    128 + signal.SIGINT,
    128 + signal.SIGTERM,
    128 + signal.SIGHUP,
}
"""Exit codes of a matrix run stopped from outside (a signal, or wrt's own exit code after one):
no result of the fault, which is not recorded and is measured again when the run resumes."""
STOP_GRACE_S = 10.0  # how long a stopped runner waits for its matrix run to end before killing it


def _run_to_end(command: list[str], scratch: str, env: dict[str, str]) -> tuple[int, str]:
    """``(exit code, stdout + stderr)`` of ``command`` run in ``scratch``, in a session of its own,
    so that a Ctrl-C at the terminal reaches this runner only. When the runner is stopped (Ctrl-C,
    SIGTERM) while it waits, the run is stopped too (SIGTERM to its process group, then SIGKILL
    after ``STOP_GRACE_S``) and waited for before the interruption goes on: no matrix process is
    left behind, and the scratch folder can be removed."""
    with tempfile.TemporaryFile(mode="w+") as output:
        proc = subprocess.Popen(
            command, cwd=scratch, env=env, stdout=output, stderr=subprocess.STDOUT, start_new_session=True
        )
        try:
            code = proc.wait()
        except BaseException:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(timeout=STOP_GRACE_S)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
            raise
        output.seek(0)
        return code, output.read()


def run_matrix_copy(scratch: str, env: dict[str, str], names, args: list[str]) -> dict:
    """``wrt matrix NAMES ARGS --json`` on the scratch copy: the JSON's ``features``, or for a run
    that crashed (no JSON: an exit code other than 0 or 1) ``{"crashed": message}``. A run stopped
    from outside (``INTERRUPTIONS``) is no result: ``WrtError``, and nothing is recorded."""
    path = os.path.join(scratch, "matrix.json")
    if os.path.exists(path):
        os.unlink(path)
    command = [sys.executable, "-m", "wrt", "matrix", *names, *args, "--json", path]
    code, output = _run_to_end(command, scratch, env)
    if code in INTERRUPTIONS:
        how = f"killed by signal {-code}" if code < 0 else f"stopped by a signal (exit code {code})"
        raise WrtError(
            f"the matrix run was {how} from outside: that is no result of the fault, which is not recorded; run "
            "wrt mutants again to resume"
        )
    if code not in (0, 1) or not os.path.exists(path):
        return {"crashed": f"exit code {code}: {output.strip()[-TAIL:]}"}
    try:
        doc = read_json(path, "matrix results", limit=RESULTS_LIMIT)
        features = _field(doc, "features", dict, "an object", "")
        for name, feature in features.items():
            _field(feature, "passed", bool, "true or false", f"features.{name}.")
            _strings(_field(feature, "failed_checks", list, "an array", f"features.{name}."), f"features.{name}.")
    except WrtError as e:  # a mutant that breaks wrt matrix --json itself
        return {"crashed": f"the matrix run wrote malformed results: {e}"}
    return {"features": features}


def measure(fault: Fault, scratch: str, env, features: list[str], mode: str, args: list[str]) -> dict:
    """Run the matrix on ``scratch`` (the fault applied): ``mode`` ``full`` (``features``),
    ``expected`` (the fault's expected features) or ``first-catch`` (the expected features one at a
    time, then the others at once, stopping at the first run that catches it)."""
    if mode == "full":
        batches = [features]
    elif mode == "expected":
        batches = [list(fault.expect)]
    else:
        batches = [[name] for name in fault.expect] + [[n for n in features if n not in fault.expect]]
    result = {"features": {}, "crashed": None}
    for batch in batches:
        if not batch:
            continue
        run = run_matrix_copy(scratch, env, batch, args)
        if "crashed" in run:
            result["crashed"] = run["crashed"]
            break
        result["features"].update(run["features"])
        if mode == "first-catch" and any(not f["passed"] for f in run["features"].values()):
            break
    caught_by = {name: f["failed_checks"] for name, f in result["features"].items() if not f["passed"]}
    result["caught_by"] = caught_by
    result["caught"] = bool(caught_by) or result["crashed"] is not None
    result["expected_caught"] = any(name in caught_by for name in fault.expect) or result["crashed"] is not None
    checks = {c for failed in caught_by.values() for c in failed} | ({CRASH} if result["crashed"] else set())
    result["checks"] = sorted(checks)
    return result


def _field(doc, key: str, types, meant: str, where: str):
    """``doc[key]`` when ``doc`` is an object holding it as one of ``types``; else ``WrtError``
    naming ``where + key`` and what it should be (``meant``)."""
    if not isinstance(doc, dict):
        raise WrtError(f"{where.rstrip('.') or 'the document'}: not an object (it holds {json_kind(doc)})")
    if key not in doc:
        raise WrtError(f"{where}{key}: missing")
    value = doc[key]
    allowed = types if isinstance(types, tuple) else (types,)
    if not isinstance(value, allowed) or (isinstance(value, bool) and bool not in allowed):
        raise WrtError(f"{where}{key}: must be {meant} (it holds {json_kind(value)})")
    return value


def _strings(values: list, where: str) -> list:
    if not all(isinstance(v, str) for v in values):
        raise WrtError(f"{where}: must be an array of strings")
    return values


def _checked_result(r, where: str) -> dict:
    """One fault's stored result ``r`` (``measure`` and ``mutants``' fields), its shape checked:
    every key that a resumed run reads, of its type."""
    _field(r, "features", dict, "an object", where)
    crashed = _field(r, "crashed", (str, type(None)), "a string or null", where)
    if crashed is not None and not crashed.strip():
        raise WrtError(f"{where}crashed: must not be empty")
    for name, checks in _field(r, "caught_by", dict, "an object", where).items():
        if not isinstance(checks, list):
            raise WrtError(f"{where}caught_by.{name}: must be an array (it holds {json_kind(checks)})")
        _strings(checks, f"{where}caught_by.{name}")
    for key in ("caught", "expected_caught"):
        _field(r, key, bool, "true or false", where)
    _strings(_field(r, "checks", list, "an array", where), f"{where}checks")
    for key in ("fault", "tree", "mode"):
        _field(r, key, str, "a string", where)
    _strings(_field(r, "args", list, "an array", where), f"{where}args")
    time_s = _field(r, "time_s", (int, float), "a number", where)
    if not time_s >= 0:
        raise WrtError(f"{where}time_s: must be a number >= 0")
    return r


def load_results(path: str) -> dict:
    """The results by fault id of the ``mutants.json`` at ``path``, each of the shape ``mutants``
    writes; ``WrtError`` naming the file and the key otherwise (not JSON, nested too deeply, an
    array where an object belongs, a missing key, a value of another type)."""
    what = "wrt mutants results"
    try:
        doc = read_json(path, what, limit=RESULTS_LIMIT)
        faults = _field(doc, "faults", dict, "an object of results by fault id", "")
        for fault_id, r in faults.items():
            _checked_result(r, f"faults.{fault_id}.")
    except WrtError as e:
        problem = str(e).removeprefix(f"{path}: ").removeprefix(f"not a {what} file: ")
        fix = "remove it or name another --report DIR"
        raise WrtError(f"{path}: not the results of wrt mutants: {problem}; {fix}") from None
    return faults


def fault_line(fault: Fault, r: dict) -> str:
    """One fault's result in words."""
    by = "; ".join(f"{name} ({', '.join(checks)})" for name, checks in r["caught_by"].items())
    if r["crashed"]:
        by = f"the matrix run crashed: {r['crashed'].splitlines()[-1]}" + (f"; {by}" if by else "")
    expected = f"expected {', '.join(fault.expect)}: {'caught' if r['expected_caught'] else 'missed'}"
    verdict = f"caught by {by}" if r["caught"] else "SURVIVED"
    return f"{fault.id} [{fault.category}]: {verdict}; {expected} ({r['time_s']:.0f} s, {r['mode']})"


def alone_counts(results: list[dict]) -> dict[str, int]:
    """Per check (``run.CHECKS`` and a crashed run), the faults that it alone caught."""
    counts = dict.fromkeys((*CHECKS, CRASH), 0)
    for r in results:
        if len(r["checks"]) == 1:
            counts[r["checks"][0]] = counts.get(r["checks"][0], 0) + 1
    return counts


def mutants(
    ids: list[str],
    report: str,
    faults_file: str | None = None,
    jobs: int = 1,
    mode: str = "full",
    kernel_cache: str | None = None,
    device: str = "cpu",
    features_file: str | None = None,
    refs: str | None = None,
) -> int:
    """Plant the faults called ``ids`` (all when empty) one at a time and run the matrix on each
    (``measure``); print a line per fault, the faults each check alone caught, and last
    ``K of N planted faults caught``. Exit 0 when all are caught, 1 when one survives."""
    from wrt.host import machine_info

    if mode not in MODES:
        raise WrtError(f"mode {mode!r}: must be one of {', '.join(MODES)}")
    if features_file is not None and refs is None:
        raise WrtError(f"--features {features_file}: name the folder of its references with --refs DIR")
    faults = load_faults(faults_file or FAULTS_FILE, features_file)
    known = {f.id: f for f in faults}
    unknown = [i for i in ids if i not in known]
    if unknown:
        raise WrtError(f"{faults_file or FAULTS_FILE}: no fault {unknown[0]!r} (known: {', '.join(known)})")
    faults = [known[i] for i in ids] if ids else faults
    results_path = os.path.join(report, RESULTS)
    # the one file written: checked before the work (a file in the folder's place, a read-only folder)
    inputs = (faults_file or FAULTS_FILE, features_file or FEATURES_FILE)
    check_output_folder(report, (RESULTS,), option="--report", protect=inputs)
    if kernel_cache:  # Warp's errors there would crash every run, and a crashed run counts as caught
        check_output_folder(kernel_cache, option="--kernel-cache")
    dirs = package_dirs()
    for fault in faults:  # before any run: a fault that no longer applies stops the whole measurement
        check_applies(fault, dirs)
    features = [f.name for f in load_features(features_file or FEATURES_FILE)]
    args = ["--jobs", str(jobs), "--device", device]
    if features_file is not None:
        args += ["--features", os.path.abspath(features_file), "--refs", os.path.abspath(refs)]
    elif refs is not None:
        args += ["--refs", os.path.abspath(refs)]
    tree = tree_digest(dirs)
    stored = load_results(results_path) if os.path.exists(results_path) else {}
    print(f"kernel cache: {kernel_cache or os.environ.get('WARP_CACHE_PATH') or 'Warp default'}", flush=True)
    results, checked = {}, False
    for fault in faults:
        old = stored.get(fault.id)
        if old and (old["fault"], old["tree"], old["mode"], old["args"]) == (fault.digest(), tree, mode, args):
            results[fault.id] = old
            print(f"{fault_line(fault, old)} [measured before: same fault and source tree]", flush=True)
            continue
        with tempfile.TemporaryDirectory(prefix=f"wrt-mutant-{fault.id}-") as scratch:
            copy_packages(dirs, scratch)
            env = _environment(scratch, kernel_cache)
            if not checked:
                check_imports(scratch, env)
                checked = True
            apply_fault(fault, scratch)
            start = time.perf_counter()
            r = measure(fault, scratch, env, features, mode, args)
        r.update(fault=fault.digest(), tree=tree, mode=mode, args=args, time_s=time.perf_counter() - start)
        results[fault.id] = r
        stored[fault.id] = r
        write_json(results_path, {"machine": machine_info(), "tree": tree, "faults": stored})
        print(fault_line(fault, r), flush=True)
    done = [results[f.id] for f in faults]
    if mode == "first-catch":
        print("checks that alone caught a fault: not counted in --first-catch mode")
    else:
        counts = alone_counts(done)
        print("checks that alone caught a fault: " + ", ".join(f"{c} {n}" for c, n in counts.items()))
    missed = [f.id for f in faults if not results[f.id]["expected_caught"]]
    if missed:
        print(f"caught by none of their expected features: {', '.join(missed)}")
    survived = [f.id for f in faults if not results[f.id]["caught"]]
    if survived:
        print(f"survived: {', '.join(survived)}")
    print(f"{len(faults) - len(survived)} of {len(faults)} planted faults caught")
    return 1 if survived else 0
