"""Heterogeneous media end to end: the ``.vol`` reader and its refusals (one line, exit 2, no
output), the scene format's volume tables, the path integrator's delta tracking against a float64
quadrature of the transmittance through a grid, a white furnace of a heterogeneous albedo-1
medium, a grid of zero majorant rendering as vacuum, and the Mitsuba importer's ``gridvolume`` and
``constvolume``. Renders take the all-features kernel (shipped compiled)."""

import math
import struct

import numpy as np
import pytest
from conftest import GOOD_SCENE
from test_bad_input import run_bad

import wrt
from wrt.errors import WrtError
from wrt.loader import parse_scene
from wrt.mitsuba import load_mitsuba
from wrt.volumes import HEADER, VolumeFileError, read_vol, write_vol

ORTHOGRAPHIC = {"type": "orthographic", "origin": [0.5, 0.5, 5.0], "look_at": [0.5, 0.5, 0.0], "width": 1.0}
NULL = {"name": "boundary", "type": "null"}
UNIT_BOX = [  # the null faces of the unit cube's front (z = 1) and back (z = 0), facing out
    {"type": "polygon", "vertices": face, "material": "boundary", "interior": "smoke"}
    for face in ([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]])
]


def ramp(n=8):
    """Density rising in x and falling in z, grey: (z, y, x)."""
    x = (np.arange(n) + 0.5) / n
    return (2.5 * x[None, None, :] * (1.2 - x[:, None, None]) + 0.1 * np.ones((n, n, n))).astype(np.float32)


def test_a_written_grid_reads_back_with_its_box(tmp_path):
    values = np.random.default_rng(1).uniform(0, 2, size=(3, 4, 5, 3)).astype(np.float32)
    write_vol(tmp_path / "g.vol", values, box=((-1, 0, 2), (1, 3, 4)))
    read, box = read_vol(tmp_path / "g.vol")
    np.testing.assert_array_equal(read, values)
    np.testing.assert_array_equal(box, [[-1, 0, 2], [1, 3, 4]])
    assert (tmp_path / "g.vol").stat().st_size == HEADER.size + 4 * values.size


def vol_bytes(nx=2, ny=2, nz=2, channels=1, values=None, magic=b"VOL", version=3, encoding=1, body=None):
    head = struct.pack("<3sBiiiii6f", magic, version, encoding, nx, ny, nz, channels, 0, 0, 0, 1, 1, 1)
    if body is None:
        body = np.full(max(nx * ny * nz * channels, 0), 0.5, "<f4") if values is None else np.asarray(values, "<f4")
        body = body.tobytes()
    return head + body


BAD_VOLUMES = [
    ("not a volume", b"PLY 3 and so on, not a grid at all, padded to length.", "not a volume file"),
    ("header cut short", vol_bytes()[:30], "shorter than the 48-byte header"),
    ("version 2", vol_bytes(version=2), "version 3"),
    ("float16 encoding", vol_bytes(encoding=2), "encoding 2"),
    ("two channels", vol_bytes(channels=2), "2 channels"),
    ("a grid of 0 cells", vol_bytes(nx=0), "holds nothing"),
    ("too large for memory", vol_bytes(nx=1 << 12, ny=1 << 12, nz=1 << 10, body=b""), "more than the"),
    ("body cut short", vol_bytes()[:-4], "header declares 32"),
    ("body too long", vol_bytes() + b"\0\0\0\0", "header declares 32"),
    ("NaN", vol_bytes(values=[0.5] * 7 + [math.nan]), "NaN or infinite"),
    ("infinite", vol_bytes(values=[math.inf] + [0.5] * 7), "NaN or infinite"),
    ("negative", vol_bytes(values=[0.5] * 7 + [-0.25]), "negative"),
]

SMOKE = """
[[medium]]
name = "smoke"
type = "heterogeneous"
sigma_t = { volume = "grid", file = "smoke.vol" }
"""


@pytest.mark.parametrize("data, message", [b[1:] for b in BAD_VOLUMES], ids=[b[0] for b in BAD_VOLUMES])
def test_a_bad_volume_file_is_one_line_and_exit_2(tmp_path, capsys, data, message):
    (tmp_path / "smoke.vol").write_bytes(data)
    run_bad(tmp_path, capsys, GOOD_SCENE + SMOKE, "medium[0].sigma_t", "file", "smoke.vol", message)


def test_the_reader_refuses_a_huge_grid_before_reading_it(tmp_path, monkeypatch):
    path = tmp_path / "huge.vol"
    path.write_bytes(vol_bytes(nx=1 << 12, ny=1 << 12, nz=1 << 10, body=b""))
    monkeypatch.setattr(np, "frombuffer", lambda *a, **k: pytest.fail("read the body"))
    with pytest.raises(VolumeFileError, match="more than the"):
        read_vol(path)


BAD_TABLES = [
    ("a number for a grid", SMOKE.replace('{ volume = "grid", file = "smoke.vol" }', "2.0"), "sigma_t", "volume table"),
    ("unknown volume kind", SMOKE.replace('"grid"', '"noise"'), "volume", "noise"),
    ("missing file", SMOKE.replace("smoke.vol", "nowhere.vol"), "file", "nowhere.vol"),
    ("albedo grid above 1", SMOKE + 'albedo = { volume = "grid", file = "bright.vol" }\n', "albedo", "at most 1"),
    ("negative constant", SMOKE.replace('"grid", file = "smoke.vol"', '"constant", value = -1'), "value"),
]


@pytest.mark.parametrize("text, fragments", [(b[1], b[2:]) for b in BAD_TABLES], ids=[b[0] for b in BAD_TABLES])
def test_bad_volume_tables_are_one_line_and_exit_2(tmp_path, capsys, text, fragments):
    write_vol(tmp_path / "smoke.vol", np.full((2, 2, 2), 0.5))
    write_vol(tmp_path / "bright.vol", np.full((2, 2, 2), 1.5))
    run_bad(tmp_path, capsys, GOOD_SCENE + text, *fragments)


def scene_doc(tmp_path, values, albedo=0.0, radiance=1.0, max_depth=4):
    write_vol(tmp_path / "smoke.vol", values)
    return {
        "render": {"width": 8, "height": 8, "integrator": "path", "max_depth": max_depth, "sampler": "independent"},
        "camera": ORTHOGRAPHIC,
        "medium": [
            {
                "name": "smoke",
                "type": "heterogeneous",
                "sigma_t": {"volume": "grid", "file": "smoke.vol"},
                "albedo": albedo,
            }
        ],
        "material": [NULL],
        "shape": UNIT_BOX,
        "light": [{"type": "environment", "radiance": [radiance] * 3}],
    }


def render(tmp_path, doc, spp, seed=1):
    scene = parse_scene(doc, file=str(tmp_path / "scene.toml"), scene_dir=str(tmp_path))
    return wrt.render(scene, spp=spp, seed=seed, specialize=False).rgb.astype(np.float64)


def pixel_transmittance(values, pixels=8, sub=8, steps=400):
    """float64 expected pixel values of the orthographic view down -z through the unit cube: the
    transmittance exp(-int sigma dz) of the trilinear grid, averaged over each pixel's area."""
    n = values.shape[0]
    grid = values.astype(np.float64)

    def lookup(x, y, z):
        coords = [np.clip(c * n - 0.5, 0, n - 1) for c in (x, y, z)]
        i0 = [np.minimum(np.floor(c).astype(int), n - 1) for c in coords]
        i1 = [np.minimum(i + 1, n - 1) for i in i0]
        f = [c - i for c, i in zip(coords, i0)]
        out = 0.0
        for corner in range(8):
            pick = [(corner >> k) & 1 for k in range(3)]
            ix, iy, iz = (i1[k] if pick[k] else i0[k] for k in range(3))
            w = np.prod([f[k] if pick[k] else 1 - f[k] for k in range(3)], axis=0)
            out = out + w * grid[iz, iy, ix]
        return out

    u = (np.arange(pixels * sub) + 0.5) / (pixels * sub)
    z = (np.arange(steps) + 0.5) / steps
    x, y, zz = np.meshgrid(u, 1.0 - u, z, indexing="xy")  # image rows run down y
    t = np.exp(-lookup(x, y, zz).sum(axis=2) / steps)
    return t.reshape(pixels, sub, pixels, sub).mean(axis=(1, 3))


def test_delta_tracking_transmits_the_quadrature_of_the_grid(tmp_path):
    """A grey absorbing grid (albedo 0) before a uniform environment: each pixel's expected value
    is its transmittance; the image mean and every column's mean are held to 4 standard errors."""
    values = ramp()
    spp = 512
    image = render(tmp_path, scene_doc(tmp_path, values), spp)[..., 0]
    expected = pixel_transmittance(values)
    assert 0.15 < expected.min() and expected.max() < 0.95
    columns = image.mean(axis=0)
    std = np.sqrt((expected * (1 - expected)).sum(axis=0) / (8 * 8 * spp))
    assert np.all(np.abs(columns - expected.mean(axis=0)) < 4 * std), (columns, expected.mean(axis=0), std)


def test_a_white_furnace_of_a_heterogeneous_medium_returns_the_environment(tmp_path):
    """Albedo 1 everywhere: light is scattered, never lost, whatever the grid (null collisions
    included), so the image is the environment's radiance."""
    image = render(tmp_path, scene_doc(tmp_path, 6.0 * ramp(), albedo=1.0, max_depth=1024), 256)
    np.testing.assert_allclose(image.mean(), 1.0, rtol=0.01)


def test_a_grid_of_zero_majorant_renders_as_vacuum(tmp_path):
    doc = scene_doc(tmp_path, np.zeros((4, 4, 4)))
    np.testing.assert_array_equal(render(tmp_path, doc, 4), 1.0)


def test_the_mitsuba_importer_converts_grid_and_constant_volumes_exactly(tmp_path):
    write_vol(tmp_path / "d.vol", ramp(4), box=((0, 0, 0), (2, 2, 2)))
    xml = tmp_path / "scene.xml"
    xml.write_text(
        """<scene version="3.0.0">
    <integrator type="volpath"/>
    <medium type="heterogeneous" id="smoke">
        <volume name="sigma_t" type="gridvolume">
            <string name="filename" value="d.vol"/><boolean name="use_grid_bbox" value="true"/>
            <transform name="to_world"><translate x="1"/></transform>
        </volume>
        <volume name="albedo" type="constvolume"><rgb name="value" value="0.5, 0.6, 0.7"/></volume>
        <float name="scale" value="3"/>
    </medium>
    <medium type="heterogeneous" id="plain"><float name="sigma_t" value="2"/></medium>
    <shape type="sphere"><bsdf type="null"/><ref id="smoke" name="interior"/><ref id="plain" name="exterior"/></shape>
</scene>"""
    )
    doc, approximations = load_mitsuba(xml)
    assert approximations == []
    smoke, plain = doc["medium"]
    assert smoke["sigma_t"]["volume"] == "grid" and smoke["sigma_t"]["use_grid_bbox"] is True
    assert smoke["sigma_t"]["transform"]["matrix"][3] == 1.0  # the translation by x = 1
    assert smoke["albedo"] == {"volume": "constant", "value": [0.5, 0.6, 0.7]}
    assert plain["sigma_t"] == {"volume": "constant", "value": [2.0] * 3}  # Mitsuba's constvolume over the unit cube
    scene = wrt.load_scene(xml)
    volume = scene.media[0].sigma_t
    np.testing.assert_allclose(volume.to_world @ [1, 1, 1, 1], [3, 2, 2, 1])  # the file's box, then to_world
    xml.write_text(xml.read_text().replace('<float name="scale" value="3"/>', '<float name="sigma_n" value="1"/>'))
    assert load_mitsuba(xml)[0]["medium"][0]["sigma_n"] == 1.0  # its null density: the noise only
    xml.write_text(xml.read_text().replace('name="sigma_n" value="1"', 'name="sigma_n" value="-1"'))
    with pytest.raises(WrtError, match="'sigma_n' = -1 must not be negative"):
        load_mitsuba(xml)
