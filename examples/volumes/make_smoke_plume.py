"""Make ``smoke_plume.vol``: a 32^3 grey grid of a rising, widening, twisting plume of smoke over
the unit cube (density up to 1: its medium's ``scale`` sets the extinction), for
examples/path/smoke_plume.toml. Deterministic; the committed file is its output. Run from this
folder: ``python make_smoke_plume.py``."""

from pathlib import Path

import numpy as np

from wrt.volumes import write_vol

N = 32
z, y, x = np.meshgrid(*((np.arange(N) + 0.5) / N,) * 3, indexing="ij")
angle = 5.0 * y  # the plume twists as it rises
cx = 0.5 + 0.12 * np.sin(angle) * y
cz = 0.5 + 0.12 * np.cos(angle) * y - 0.12 * y
width = 0.06 + 0.28 * y  # and widens
r2 = ((x - cx) ** 2 + (z - cz) ** 2) / width**2
puffs = 0.65 + 0.35 * np.sin(23.0 * y + 7.0 * x) * np.sin(17.0 * z - 5.0 * y)
density = np.exp(-2.0 * r2) * puffs * np.clip(1.2 - y, 0.0, 1.0) * np.clip(8.0 * y, 0.0, 1.0)
write_vol(Path(__file__).parent / "smoke_plume.vol", np.clip(density, 0.0, 1.0))
