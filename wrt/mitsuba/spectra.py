"""Mitsuba 3 spectra as its RGB variants (``scalar_rgb``) read them: wavelength:value pairs,
from a ``<spectrum value="400:0.1, 500:0.5">`` or a ``.spd`` file, integrated against the CIE 1931
colour matching functions into linear sRGB (Rec. 709 primaries, D65 white), exactly as Mitsuba's
``spectrum_list_to_srgb`` does.

Mitsuba's scene parser (``Properties::get_texture_impl``) converts a spectral parameter by kind:

- a reflectance: the pairs weighted by illuminant D65, the sRGB clamped to [0, 1] ("bounded");
  a constant ``value="v"`` is grey ``v``;
- an unbounded parameter (a conductor's ``eta`` and ``k``): weighted by D65, clamped at 0;
  a constant is grey;
- an emission (``radiance``, ``intensity``, ``irradiance``): not weighted, clamped at 0; a
  constant is ``v * XYZ_TO_SRGB @ (1, 1, 1)``, slightly purple (equal energy seen in sRGB,
  whose white is D65), so that RGB variants match the spectral ones.

Wavelengths are in nm and must increase; any are accepted, only the part of the spectrum within
[360, 830] nm counts, and no value is assumed beyond the first and last wavelength (zero there).

References
----------
CIE 1931 2-degree standard observer, colour matching functions at 5 nm from 360 to 830 nm:
CIE 015:2004 *Colorimetry*, 3rd ed., table T.4, in the digits of the Colour & Vision Research
Laboratory's ``ciexyz31`` table (cvrl.org), which Mitsuba 3 tabulates (``src/core/spectrum.cpp``).
CIE standard illuminant D65, relative spectral power (100 at 560 nm), 5 nm: CIE 015:2004 table T.1
(ISO 11664-2), as in Mitsuba 3 (``include/mitsuba/core/spectrum.h``).
"""

from __future__ import annotations

import numpy as np

CIE_MIN, CIE_MAX = 360.0, 830.0
"""The wavelengths, in nm, over which Mitsuba integrates a spectrum (``MI_CIE_MIN``, ``MI_CIE_MAX``)."""

CIE_TABLE = np.array(
    [  # wavelength (nm), x_bar, y_bar, z_bar, D65 relative power
        [360, 0.0001299, 3.917e-6, 0.0006061, 46.6383],
        [365, 0.0002321, 6.965e-6, 0.001086, 49.3637],
        [370, 0.0004149, 1.239e-5, 0.001946, 52.0891],
        [375, 0.0007416, 2.202e-5, 0.003486, 51.0323],
        [380, 0.001368, 3.9e-5, 0.006450001, 49.9755],
        [385, 0.002236, 6.4e-5, 0.01054999, 52.3118],
        [390, 0.004243, 0.00012, 0.02005001, 54.6482],
        [395, 0.00765, 0.000217, 0.03621, 68.7015],
        [400, 0.01431, 0.000396, 0.06785001, 82.7549],
        [405, 0.02319, 0.00064, 0.1102, 87.1204],
        [410, 0.04351, 0.00121, 0.2074, 91.486],
        [415, 0.07763, 0.00218, 0.3713, 92.4589],
        [420, 0.13438, 0.004, 0.6456, 93.4318],
        [425, 0.21477, 0.0073, 1.0390501, 90.057],
        [430, 0.2839, 0.0116, 1.3856, 86.6823],
        [435, 0.3285, 0.01684, 1.62296, 95.7736],
        [440, 0.34828, 0.023, 1.74706, 104.865],
        [445, 0.34806, 0.0298, 1.7826, 110.936],
        [450, 0.3362, 0.038, 1.77211, 117.008],
        [455, 0.3187, 0.048, 1.7441, 117.41],
        [460, 0.2908, 0.06, 1.6692, 117.812],
        [465, 0.2511, 0.0739, 1.5281, 116.336],
        [470, 0.19536, 0.09098, 1.28764, 114.861],
        [475, 0.1421, 0.1126, 1.0419, 115.392],
        [480, 0.09564, 0.13902, 0.8129501, 115.923],
        [485, 0.05795001, 0.1693, 0.6162, 112.367],
        [490, 0.03201, 0.20802, 0.46518, 108.811],
        [495, 0.0147, 0.2586, 0.3533, 109.082],
        [500, 0.0049, 0.323, 0.272, 109.354],
        [505, 0.0024, 0.4073, 0.2123, 108.578],
        [510, 0.0093, 0.503, 0.1582, 107.802],
        [515, 0.0291, 0.6082, 0.1117, 106.296],
        [520, 0.06327, 0.71, 0.07824999, 104.79],
        [525, 0.1096, 0.7932, 0.05725001, 106.239],
        [530, 0.1655, 0.862, 0.04216, 107.689],
        [535, 0.2257499, 0.9148501, 0.02984, 106.047],
        [540, 0.2904, 0.954, 0.0203, 104.405],
        [545, 0.3597, 0.9803, 0.0134, 104.225],
        [550, 0.4334499, 0.9949501, 0.008749999, 104.046],
        [555, 0.5120501, 1.0, 0.005749999, 102.023],
        [560, 0.5945, 0.995, 0.0039, 100.0],
        [565, 0.6784, 0.9786, 0.002749999, 98.1671],
        [570, 0.7621, 0.952, 0.0021, 96.3342],
        [575, 0.8425, 0.9154, 0.0018, 96.0611],
        [580, 0.9163, 0.87, 0.001650001, 95.788],
        [585, 0.9786, 0.8163, 0.0014, 92.2368],
        [590, 1.0263, 0.757, 0.0011, 88.6856],
        [595, 1.0567, 0.6949, 0.001, 89.3459],
        [600, 1.0622, 0.631, 0.0008, 90.0062],
        [605, 1.0456, 0.5668, 0.0006, 89.8026],
        [610, 1.0026, 0.503, 0.00034, 89.5991],
        [615, 0.9384, 0.4412, 0.00024, 88.6489],
        [620, 0.8544499, 0.381, 0.00019, 87.6987],
        [625, 0.7514, 0.321, 1e-4, 85.4936],
        [630, 0.6424, 0.265, 4.999999e-5, 83.2886],
        [635, 0.5419, 0.217, 3e-5, 83.4939],
        [640, 0.4479, 0.175, 2e-5, 83.6992],
        [645, 0.3608, 0.1382, 1e-5, 81.863],
        [650, 0.2835, 0.107, 0.0, 80.0268],
        [655, 0.2187, 0.0816, 0.0, 80.1207],
        [660, 0.1649, 0.061, 0.0, 80.2146],
        [665, 0.1212, 0.04458, 0.0, 81.2462],
        [670, 0.0874, 0.032, 0.0, 82.2778],
        [675, 0.0636, 0.0232, 0.0, 80.281],
        [680, 0.04677, 0.017, 0.0, 78.2842],
        [685, 0.0329, 0.01192, 0.0, 74.0027],
        [690, 0.0227, 0.00821, 0.0, 69.7213],
        [695, 0.01584, 0.005723, 0.0, 70.6652],
        [700, 0.01135916, 0.004102, 0.0, 71.6091],
        [705, 0.008110916, 0.002929, 0.0, 72.979],
        [710, 0.005790346, 0.002091, 0.0, 74.349],
        [715, 0.004109457, 0.001484, 0.0, 67.9765],
        [720, 0.002899327, 0.001047, 0.0, 61.604],
        [725, 0.00204919, 0.00074, 0.0, 65.7448],
        [730, 0.001439971, 0.00052, 0.0, 69.8856],
        [735, 0.0009999493, 0.0003611, 0.0, 72.4863],
        [740, 0.0006900786, 0.0002492, 0.0, 75.087],
        [745, 0.0004760213, 0.0001719, 0.0, 69.3398],
        [750, 0.0003323011, 0.00012, 0.0, 63.5927],
        [755, 0.0002348261, 8.48e-5, 0.0, 55.0054],
        [760, 0.0001661505, 6e-5, 0.0, 46.4182],
        [765, 0.000117413, 4.24e-5, 0.0, 56.6118],
        [770, 8.307527e-5, 3e-5, 0.0, 66.8054],
        [775, 5.870652e-5, 2.12e-5, 0.0, 65.0941],
        [780, 4.150994e-5, 1.499e-5, 0.0, 63.3828],
        [785, 2.935326e-5, 1.06e-5, 0.0, 63.8434],
        [790, 2.067383e-5, 7.4657e-6, 0.0, 64.304],
        [795, 1.455977e-5, 5.2578e-6, 0.0, 61.8779],
        [800, 1.025398e-5, 3.7029e-6, 0.0, 59.4519],
        [805, 7.221456e-6, 2.6078e-6, 0.0, 55.7054],
        [810, 5.085868e-6, 1.8366e-6, 0.0, 51.959],
        [815, 3.581652e-6, 1.2934e-6, 0.0, 54.6998],
        [820, 2.522525e-6, 9.1093e-7, 0.0, 57.4406],
        [825, 1.776509e-6, 6.4153e-7, 0.0, 58.8765],
        [830, 1.251141e-6, 4.5181e-7, 0.0, 60.3125],
    ]
)
"""The CIE 1931 2-degree colour matching functions and illuminant D65 at 5 nm, 360-830 nm (see
References); Mitsuba interpolates each column linearly between these wavelengths."""

CIE_Y_NORMALIZATION = 1.0 / 106.7502593994140625
"""Mitsuba's ``MI_CIE_Y_NORMALIZATION``: divides the XYZ integrals so that a spectrum equal to 1
over 360-830 nm has luminance Y = 1."""

CIE_D65_NORMALIZATION = 1.0 / 98.99741751876255
"""Mitsuba's ``MI_CIE_D65_NORMALIZATION``: scales the D65 column so that D65 has the luminance
of a spectrum equal to 1 (the integral of y_bar times D65 becomes that of y_bar)."""

XYZ_TO_SRGB = np.array(
    [
        [3.240479, -1.537150, -0.498535],
        [-0.969256, 1.875991, 0.041556],
        [0.055648, -0.204043, 1.057311],
    ]
)
"""CIE XYZ to linear sRGB (ITU-R BT.709 primaries), the matrix of Mitsuba's ``xyz_to_srgb``."""

SAMPLES = 1000
"""Wavelengths Mitsuba samples the integral at, evenly over [360, 830] nm, both ends included
(its Riemann sum weights each by (830 - 360) / 1000 nm)."""


def spectrum_to_srgb(wavelengths, values, *, bounded: bool = True, d65: bool = False) -> np.ndarray:
    """The linear sRGB of a spectrum, as Mitsuba's ``spectrum_list_to_srgb``.

    Parameters
    ----------
    wavelengths : sequence of float
        Increasing wavelengths in nm, at least two.
    values : sequence of float
        The spectrum at ``wavelengths`` (linearly interpolated between them; zero outside).
    bounded : bool, default True
        Clamp the result to [0, 1] (a reflectance); otherwise only negative channels become 0.
    d65 : bool, default False
        Weight the spectrum by illuminant D65 (Mitsuba does for every parameter but emission).

    Returns
    -------
    numpy.ndarray of float64, shape (3,)
        Linear sRGB: ``XYZ_TO_SRGB @ sum(cmf(w) * value(w) [* D65(w)]) * 470 / SAMPLES *
        CIE_Y_NORMALIZATION`` over the ``SAMPLES`` wavelengths within the spectrum's range.

    Raises
    ------
    ValueError
        Fewer than two wavelengths, wavelengths that do not increase, or an integral that
        overflows float64.
    """
    wavelengths, values = np.asarray(wavelengths, dtype=np.float64), np.asarray(values, dtype=np.float64)
    if wavelengths.size < 2:
        raise ValueError("a spectrum needs at least two wavelength:value pairs")
    increasing = np.diff(wavelengths) > 0
    if not increasing.all():
        i = int(np.argmin(increasing))
        raise ValueError(f"wavelengths must increase ({wavelengths[i]:g} then {wavelengths[i + 1]:g})")
    w = CIE_MIN + np.arange(SAMPLES) / (SAMPLES - 1) * (CIE_MAX - CIE_MIN)
    w = w[(w >= wavelengths[0]) & (w <= wavelengths[-1])]
    with np.errstate(over="ignore", invalid="ignore"):
        weight = np.interp(w, wavelengths, values)
        if d65:
            weight = weight * np.interp(w, CIE_TABLE[:, 0], CIE_TABLE[:, 4]) * CIE_D65_NORMALIZATION
        cmf = np.stack([np.interp(w, CIE_TABLE[:, 0], CIE_TABLE[:, k]) for k in (1, 2, 3)])
        xyz = cmf @ weight * ((CIE_MAX - CIE_MIN) / SAMPLES * CIE_Y_NORMALIZATION)
        rgb = XYZ_TO_SRGB @ xyz
    if not np.isfinite(rgb).all():
        raise ValueError("its integral overflows float64")
    return np.clip(rgb, 0.0, 1.0) if bounded else np.maximum(rgb, 0.0)


def uniform_to_srgb(value: float, *, emission: bool) -> np.ndarray:
    """The linear sRGB Mitsuba gives a constant spectrum ``value``: grey, except for an emission,
    which is ``value * XYZ_TO_SRGB @ (1, 1, 1)``, about (1.205, 0.948, 0.909) times ``value``."""
    return value * XYZ_TO_SRGB.sum(axis=1) if emission else np.full(3, float(value))


def spd_lines(text: str) -> list[tuple[int, str, str]]:
    """The (line number, wavelength, value) words of a ``.spd`` file, read as Mitsuba does: a
    line that is empty or starts with ``#`` is skipped; any other starts with a wavelength and a
    value separated by white space, and the rest of it (a ``#`` comment, a third column) is
    ignored. A line with less (even one of only spaces, or an indented comment) is a ValueError
    naming it by its number and its count of words, never quoting it: a file that is no spectrum
    file, such as ``/etc/shadow``, must not reach the message."""
    found = []
    for number, line in enumerate(text.split("\n"), 1):
        if line[:1] in ("", "#", "\r"):
            continue
        words = line.split("#", 1)[0].split()
        if len(words) < 2:
            raise ValueError(
                f"line {number} has {len(words)} word{'' if len(words) == 1 else 's'}, not 'wavelength value'"
            )
        found.append((number, words[0], words[1]))
    return found
