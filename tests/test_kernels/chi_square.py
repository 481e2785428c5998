"""The chi-square test of a BSDF's sampling against its density, as Mitsuba 3's ``chi2`` tests
its BSDFs: sampled directions histogrammed over a (cos theta, phi) grid of the upper hemisphere
against the density integrated over each cell (Simpson, 7 x 7 nodes a cell), the lightest cells
pooled until they expect 20."""

from typing import NamedTuple

import numpy as np
from scipy.stats import chi2


class ChiSquare(NamedTuple):
    p_value: float
    observed: float  # the samples in the hemisphere
    expected: float  # the integral of the density over it, times the samples drawn


def hemisphere_chi_square(wi: np.ndarray, pdf_of, count: int, res_t: int = 40, res_p: int = 80) -> ChiSquare:
    """The test of ``wi`` (the directions kept of ``count`` drawn; unit vectors, z up) against
    ``pdf_of(directions) -> densities`` (1/sr)."""
    cos_t, phi = wi[:, 2], np.arctan2(wi[:, 1], wi[:, 0]) % (2 * np.pi)
    observed, _, _ = np.histogram2d(cos_t, phi, bins=[res_t, res_p], range=[[0, 1], [0, 2 * np.pi]])
    nodes = 7
    s = np.linspace(0.0, 1.0, nodes)
    simpson = np.array([1, 4, 2, 4, 2, 4, 1], float) / 18.0
    ct = ((np.arange(res_t)[:, None] + s[None]) / res_t).ravel()
    ph = ((np.arange(res_p)[:, None] + s[None]) / res_p * 2 * np.pi).ravel()
    ctg, phg = np.meshgrid(ct, ph, indexing="ij")
    st = np.sqrt(np.maximum(0.0, 1 - ctg**2))
    dirs = np.stack([st * np.cos(phg), st * np.sin(phg), ctg], -1).reshape(-1, 3)
    values = np.asarray(pdf_of(dirs), dtype=np.float64).reshape(res_t, nodes, res_p, nodes)
    cell = (1.0 / res_t) * (2 * np.pi / res_p)  # the (cos theta, phi) square's area element is the solid angle
    expected = np.einsum("injm,n,m->ij", values, simpson, simpson) * cell * count
    order = np.argsort(expected.ravel())
    e, o = expected.ravel()[order], observed.ravel()[order]
    pooled = np.cumsum(e) < 20.0  # the lightest cells, pooled into one with the next
    pooled[np.argmin(pooled)] = True
    e = np.append(e[~pooled], e[pooled].sum())
    o = np.append(o[~pooled], o[pooled].sum())
    statistic = np.sum((o - e) ** 2 / e)
    return ChiSquare(float(chi2.sf(statistic, len(e) - 1)), float(observed.sum()), float(expected.sum()))
