"""wrt's example scenes and meshes, installed with the library as package data (``wrt.examples``):
``importlib.resources.files("wrt.examples")`` is this folder. See README.md and docs/."""
