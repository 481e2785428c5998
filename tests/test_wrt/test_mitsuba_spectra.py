"""Mitsuba spectra in RGB (wrt/mitsuba/spectra.py and `Plugin.color`): the CIE tables and the
conversion checked against closed forms and, where Mitsuba 3 is installed, against Mitsuba's own
``scalar_rgb`` conversion (``mi.spectrum_list_to_srgb``) and its parser's reading of the same
scene files; the importer's refusals of malformed spectra."""

import textwrap

import numpy as np
import pytest
from wrt_harness.mitsuba_peer import mitsuba_available

from wrt.errors import WrtError
from wrt.mitsuba import load_mitsuba, spectra

MITSUBA, MITSUBA_REASON = mitsuba_available()
needs_mitsuba = pytest.mark.skipif(not MITSUBA, reason=MITSUBA_REASON)

SMOOTH = "400:0.1, 500:0.5, 600:0.9, 700:0.3"
WARM = "400:1, 500:3, 600:18, 700:20"  # an emission wrt used to grey to its mean, 10.5
SPECTRA = {  # name: "wavelength:value, ..." as a scene file writes it
    "smooth reflectance": SMOOTH,
    "narrow peaks": "440:0, 445:1, 450:0, 540:0, 545:1, 550:0, 640:0, 645:0.8, 650:0",
    "warm emitter": WARM,
    "out of gamut (clamped)": "500:0, 520:1, 540:0",
    "above 1 (clamped when bounded)": "380:1.5, 480:2.5, 780:3",
    "partly outside 360-830 nm": "300:1, 450:0.2, 900:0.7",
}
SPD = (
    "# a red reflectance, as Mitsuba's .spd files are written\n400 0.05\n\n550 0.1 # a comment\r\n600\t0.8\n700 0.9 7\n"
)
"""A .spd file with what Mitsuba's reader allows: comments, a blank line, CRLF, a tab, a third column."""


def pairs(text):
    """The wavelengths and values of ``"400:0.1, 500:0.5"``."""
    return np.array([[float(x) for x in pair.split(":")] for pair in text.split(", ")]).T


def mitsuba_module():
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    return mi


def write(tmp_path, body, name="scene.xml"):
    """A Mitsuba scene file whose <scene> holds ``body`` (its first line is line 2)."""
    path = tmp_path / name
    path.write_text(f'<scene version="3.0.0">\n{textwrap.dedent(body).strip()}\n</scene>\n')
    return path


def scene(tmp_path, spectrum):
    """A scene with one spectrum, ``value="..."`` or ``filename="..."``, in every kind of colour
    parameter: a diffuse reflectance (bounded), a conductor's eta and k (unbounded) and the
    emission of each emitter type. Mitsuba's ids name them in ``mi.traverse``."""
    return write(
        tmp_path,
        f"""
        <bsdf type="diffuse" id="paint"><spectrum name="reflectance" {spectrum}/></bsdf>
        <bsdf type="conductor" id="metal">
            <spectrum name="eta" {spectrum}/><spectrum name="k" {spectrum}/>
        </bsdf>
        <shape type="sphere"><ref id="paint"/></shape>
        <shape type="sphere"><point name="center" value="3 0 0"/><ref id="metal"/></shape>
        <shape type="sphere" id="lamp">
            <point name="center" value="-3 0 0"/>
            <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
            <emitter type="area"><spectrum name="radiance" {spectrum}/></emitter>
        </shape>
        <emitter type="point" id="bulb"><spectrum name="intensity" {spectrum}/></emitter>
        <emitter type="spot" id="spot"><spectrum name="intensity" {spectrum}/></emitter>
        <emitter type="directional" id="sun"><spectrum name="irradiance" {spectrum}/></emitter>
        <emitter type="constant" id="sky"><spectrum name="radiance" {spectrum}/></emitter>
        """,
    )


TRAVERSED = (
    "paint.reflectance.value",
    "metal.eta.value",
    "metal.k.value",
    "lamp.emitter.radiance.value",
    "bulb.intensity.value",
    "spot.intensity.value",
    "sun.irradiance.value",
    "sky.radiance.value",
)
"""The parameters of `scene` as ``mi.traverse`` names them."""


def converted_colours(path):
    """What wrt made of `scene`'s colours: ``{mitsuba parameter: rgb}``."""
    doc, _ = load_mitsuba(path)
    materials = {m["name"]: m for m in doc["material"]}
    lights = {light["type"]: light for light in doc["light"]}
    return {
        "paint.reflectance.value": materials["paint"]["albedo"],
        "metal.eta.value": materials["metal"]["eta"],
        "metal.k.value": materials["metal"]["k"],
        "lamp.emitter.radiance.value": lights["sphere"]["radiance"],
        "bulb.intensity.value": lights["point"]["intensity"],
        "spot.intensity.value": lights["spot"]["intensity"],
        "sun.irradiance.value": lights["directional"]["irradiance"],
        "sky.radiance.value": lights["environment"]["radiance"],
    }


def mitsuba_colours(path):
    """Mitsuba's RGB of the same parameters."""
    mi = mitsuba_module()
    params = mi.traverse(mi.load_file(str(path)))
    return {key: np.broadcast_to(np.asarray(params[key], dtype=np.float64), (3,)) for key in TRAVERSED}


def assert_close(ours, theirs):
    """Within 1% per channel, or 1e-4 absolute for channels near 0."""
    np.testing.assert_allclose(np.asarray(ours, dtype=np.float64), theirs, rtol=0.01, atol=1e-4)


# --- the tables and the conversion, against closed forms ------------------------------------------


def test_tables_are_cie_1931_and_d65_at_5_nm():
    table = spectra.CIE_TABLE
    np.testing.assert_array_equal(table[:, 0], np.arange(360, 831, 5))
    assert table[np.argmax(table[:, 2]), 0] == 555 and table[:, 2].max() == 1.0  # y_bar peaks at 1, 555 nm
    assert table[table[:, 0] == 560, 4] == 100.0  # D65 is relative to its power at 560 nm
    assert np.all(table[:, 1:] >= 0)


def test_unit_spectra_are_white():
    """A unit emission over 360-830 nm has luminance 1 (``CIE_Y_NORMALIZATION``); a unit
    reflectance, lit by D65, is sRGB white (1, 1, 1); Mitsuba's constant emission is the unit
    spectrum seen in sRGB."""
    emission = spectra.spectrum_to_srgb([360, 830], [1, 1], bounded=False)
    assert np.linalg.solve(spectra.XYZ_TO_SRGB, emission)[1] == pytest.approx(1.0, abs=1e-4)
    np.testing.assert_allclose(spectra.spectrum_to_srgb([360, 830], [1, 1], d65=True), 1.0, atol=2e-3)
    np.testing.assert_allclose(spectra.uniform_to_srgb(1.0, emission=True), emission, rtol=1e-3)
    np.testing.assert_array_equal(spectra.uniform_to_srgb(0.25, emission=False), [0.25, 0.25, 0.25])


def test_conversion_is_linear_clamped_and_limited_to_the_visible():
    wavelengths, values = pairs(SMOOTH)
    once = spectra.spectrum_to_srgb(wavelengths, values, bounded=False, d65=True)
    np.testing.assert_allclose(spectra.spectrum_to_srgb(wavelengths, 3 * values, bounded=False, d65=True), 3 * once)
    assert np.all(spectra.spectrum_to_srgb([360, 830], [2, 2], bounded=True, d65=True) == 1.0)
    assert np.all(spectra.spectrum_to_srgb([360, 830], [2, 2], bounded=False, d65=True) > 1.9)
    assert not spectra.spectrum_to_srgb([100, 350], [5, 5], bounded=False).any()  # all below 360 nm
    green = spectra.spectrum_to_srgb(*pairs(SPECTRA["out of gamut (clamped)"]), bounded=False)
    assert green[0] == 0.0 and green[1] > 0  # negative red clamped at 0


@pytest.mark.parametrize(
    "wavelengths, problem",
    [([500], "at least two"), ([500, 400], "increase (500 then 400)"), ([400, 400], "increase (400 then 400)")],
)
def test_conversion_refuses_malformed_wavelengths(wavelengths, problem):
    with pytest.raises(ValueError, match=problem.replace("(", r"\(").replace(")", r"\)")):
        spectra.spectrum_to_srgb(wavelengths, np.ones(len(wavelengths)))


# --- against Mitsuba 3 -----------------------------------------------------------------------------


@needs_mitsuba
def test_tables_match_mitsubas():
    mi = mitsuba_module()
    for w in np.linspace(360, 830, 199):  # the 5 nm knots and between them (Mitsuba interpolates in float32)
        row = [np.interp(w, spectra.CIE_TABLE[:, 0], spectra.CIE_TABLE[:, k]) for k in range(1, 5)]
        np.testing.assert_allclose(row[:3], list(mi.cie1931_xyz(float(w))), rtol=1e-5, atol=1e-9)
        assert row[3] * spectra.CIE_D65_NORMALIZATION == pytest.approx(mi.cie_d65(float(w)), rel=1e-5)
    assert spectra.CIE_Y_NORMALIZATION == pytest.approx(mi.MI_CIE_Y_NORMALIZATION, rel=1e-12)
    assert spectra.CIE_D65_NORMALIZATION == pytest.approx(mi.MI_CIE_D65_NORMALIZATION, rel=1e-12)


@needs_mitsuba
@pytest.mark.parametrize("bounded", [True, False])
@pytest.mark.parametrize("d65", [True, False])
@pytest.mark.parametrize("name", list(SPECTRA))
def test_conversion_matches_mitsubas(name, bounded, d65):
    wavelengths, values = pairs(SPECTRA[name])
    theirs = mitsuba_module().spectrum_list_to_srgb(list(wavelengths), list(values), bounded, d65)
    assert_close(spectra.spectrum_to_srgb(wavelengths, values, bounded=bounded, d65=d65), list(theirs))


@needs_mitsuba
@pytest.mark.parametrize("name", list(SPECTRA))
def test_imported_spectra_match_mitsubas_parser(tmp_path, name):
    """Reflectance (bounded, D65-weighted), eta and k (unbounded) and every emitter's emission
    (unweighted), as Mitsuba's parser converts them from the same file."""
    path = scene(tmp_path, f'value="{SPECTRA[name]}"')
    theirs = mitsuba_colours(path)
    for key, ours in converted_colours(path).items():
        assert_close(ours, theirs[key])


@needs_mitsuba
def test_spd_file_matches_mitsuba(tmp_path):
    """A ``.spd`` file found through ``<path>``, as Mitsuba's resolver finds it."""
    (tmp_path / "spectra").mkdir()
    (tmp_path / "spectra" / "red.spd").write_text(SPD)
    path = scene(tmp_path, 'filename="red.spd"')
    path.write_text(path.read_text().replace("<bsdf", '<path value="spectra"/>\n<bsdf', 1))
    theirs = mitsuba_colours(path)
    for key, ours in converted_colours(path).items():
        assert_close(ours, theirs[key])


@needs_mitsuba
def test_constant_spectra_match_mitsuba(tmp_path):
    """``value="0.7"``: grey for a reflectance, eta and k; sRGB's view of equal energy, a little
    purple, for an emission."""
    path = scene(tmp_path, 'value="0.7"')
    theirs = mitsuba_colours(path)
    ours = converted_colours(path)
    for key in ours:
        assert_close(ours[key], theirs[key])
    assert ours["paint.reflectance.value"] == [0.7, 0.7, 0.7]
    assert ours["bulb.intensity.value"][0] > 0.8 > ours["bulb.intensity.value"][1]


# --- the importer -------------------------------------------------------------------------------


def test_imported_reflectance_is_converted_without_warning(tmp_path):
    """A spectral diffuse reflectance and emission convert exactly: no approximation to refuse."""
    path = write(
        tmp_path,
        f"""
        <shape type="sphere"><bsdf type="diffuse" id="paint">
            <spectrum name="reflectance" value="{SMOOTH}"/>
        </bsdf></shape>
        <emitter type="point"><spectrum name="intensity" value="{WARM}"/></emitter>
        """,
    )
    doc, approximations = load_mitsuba(path)
    assert approximations == []
    albedo = spectra.spectrum_to_srgb(*pairs(SMOOTH), bounded=True, d65=True)
    np.testing.assert_allclose(doc["material"][0]["albedo"], albedo)
    np.testing.assert_allclose(doc["material"][0]["albedo"], [0.8548, 0.6875, 0.2650], atol=1e-4)  # Mitsuba 3.9.1
    intensity = doc["light"][0]["intensity"]
    assert intensity[0] > 10.5 > intensity[2]  # not the grey mean


MALFORMED = [  # spectrum attributes, .spd text (None: no file), what the message names
    ('value="500:1, 400:1"', None, "'reflectance' = '500:1, 400:1': wavelengths must increase (500 then 400)"),
    ('value="400:1, 400:1"', None, "wavelengths must increase (400 then 400)"),
    ('value="400:0.5"', None, "'reflectance' = '400:0.5': a spectrum needs at least two"),
    ('value="400:0.5, 500:abc"', None, "'reflectance' = '400:0.5, 500:abc': 'abc' is not a number"),
    ('value="400 : 0.5, 500:1"', None, "'400' is not a wavelength:value pair"),
    ('value="0.5 0.7"', None, "'0.5 0.7' must be one number"),
    ('filename="none.spd"', None, "'reflectance' file 'none.spd': no such file"),
    ('filename="bad.spd"', "400 0.1\n500 x\n", "'reflectance' file 'bad.spd': line 2: 'x' is not a number"),
    (
        'filename="bad.spd"',
        "400 0.1\n   # indented\n",
        "'reflectance' file 'bad.spd': line 2 has 0 words, not 'wavelength value'",
    ),
    ('filename="bad.spd"', "400 0.1\n500 0.2\n450 0.3\n", "wavelengths must increase (500 then 450)"),
    ('value="0.5" filename="bad.spd"', "400 0.1\n500 0.2\n", "needs either a 'value' or a 'filename'"),
    ("", None, "needs either a 'value' or a 'filename'"),
    ('value="400:0.5, 500:1" unit="nm"', None, "unexpected attribute 'unit'"),
]


@pytest.mark.parametrize("attributes, spd, message", MALFORMED)
def test_malformed_spectra_are_errors_naming_file_line_and_value(tmp_path, attributes, spd, message):
    if spd is not None:
        (tmp_path / "bad.spd").write_text(spd)
    spectrum = f'<spectrum name="reflectance" {attributes}/>'
    path = write(tmp_path, f'<shape type="sphere"><bsdf type="diffuse">\n{spectrum}\n</bsdf></shape>')
    with pytest.raises(WrtError) as error:
        load_mitsuba(path, approximate=True)
    assert 'scene.xml:3: <spectrum name="reflectance">: ' in str(error.value)
    assert message in str(error.value)


@needs_mitsuba
@pytest.mark.parametrize("attributes, spd, message", MALFORMED)
def test_mitsuba_refuses_the_same_spectra(tmp_path, attributes, spd, message):
    if spd is not None:
        (tmp_path / "bad.spd").write_text(spd)
    path = write(tmp_path, f'<bsdf type="diffuse">\n<spectrum name="reflectance" {attributes}/>\n</bsdf>')
    with pytest.raises(Exception):
        mitsuba_module().load_file(str(path))
