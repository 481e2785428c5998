"""The layering the README promises ("How it is built"), read from the sources' import
statements (those inside functions too): the kernels import only Warp (and numpy, for what a
material family bakes on the host), the standard library and each other; nothing under ``wrt``
imports the harness or the benchmarks (they reach the ``wrt`` command through entry points)."""

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
KERNEL_ALLOWED = {"warp", "numpy"}  # besides the standard library and wrt.kernels itself (numpy: what a family bakes)


def imports(path: Path) -> list[tuple[int, str]]:
    """(line, module name) of every import in ``path``; relative imports keep their leading dots."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            found.append((node.lineno, "." * node.level + (node.module or "")))
    return found


def sources(folder: str) -> list[Path]:
    return sorted((ROOT / folder).rglob("*.py"))


@pytest.mark.parametrize("path", sources("kernels"), ids=lambda p: p.name)
def test_kernels_import_only_warp_and_each_other(path):
    depth = len(path.relative_to(ROOT / "kernels").parts)  # 1: kernels/x.py, 2: kernels/materials/x.py
    for line, name in imports(path):
        if name.startswith("."):
            level = len(name) - len(name.lstrip("."))
            assert level <= depth, f"{path.name}:{line}: {name} leaves wrt.kernels"
            continue
        top = name.split(".")[0]
        assert top in KERNEL_ALLOWED or top in sys.stdlib_module_names or name.startswith("wrt.kernels"), (
            f"kernels/{path.name}:{line} imports {name}: the kernels know nothing of the host"
        )


@pytest.mark.parametrize("folder", ["wrt", "kernels"])
def test_the_library_never_imports_the_harness_or_the_benchmarks(folder):
    offenders = [
        f"{path.relative_to(ROOT)}:{line} imports {name}"
        for path in sources(folder)
        for line, name in imports(path)
        if name.split(".")[0] in ("wrt_harness", "wrt_benchmarks")
    ]
    assert not offenders, offenders


def test_the_check_sees_imports_inside_functions(tmp_path):
    """The reader is not blind: a late import and a relative one are both found."""
    probe = tmp_path / "probe.py"
    probe.write_text("def f():\n    import wrt_harness.run\n    from ..scene import Scene\n")
    assert imports(probe) == [(2, "wrt_harness.run"), (3, "..scene")]
