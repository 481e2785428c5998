"""Packaging: every package of the source tree is installed (a folder missing from pyproject's
list would work in a checkout and fail after ``pip install .``)."""

import subprocess
import sys

import tomllib
from conftest import ROOT


def test_every_package_folder_is_listed_in_pyproject():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    folders = {name: path for name, path in config["package-dir"].items()}
    folders.setdefault("wrt", "wrt")
    found = set()
    for name, folder in folders.items():
        base = ROOT / folder
        for init in base.rglob("__init__.py"):
            relative = init.parent.relative_to(base)
            if relative.parts and (relative.parts[0] in folders.values() or "__pycache__" in relative.parts):
                continue
            found.add(".".join((name, *relative.parts)))
    assert found - listed == set(), "packages missing from [tool.setuptools] packages"
    assert listed - found == set(), "listed packages without a folder"


def test_import_leaves_the_garbage_collector_as_it_found_it():
    # wrt pauses the cyclic collector while it imports (see wrt/__init__.py), and must restore it
    for before, expected in (("", "True"), ("gc.disable(); ", "False")):
        code = f"import gc; {before}import wrt; print(gc.isenabled())"
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
        assert out.strip() == expected
