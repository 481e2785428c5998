"""Bad input beyond test_loader.py and test_meshio.py: malformed files, wrong types,
bad meshes through the command line, absurd sizes, memory limits, and a fuzz test of the loader.

Every case: one line ``wrt: error: ...`` naming the file, the key and the value, exit code 2, and
no output file (not even a temporary one).
"""

import copy
import dataclasses
import math
import os
import shutil
import tempfile

import numpy as np
import pytest
import warp as wp
from conftest import EXAMPLES, GOOD_SCENE
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from wrt.kernels.film import Film

import wrt
import wrt.loader
import wrt.renderer
from wrt.cli import main
from wrt.errors import WrtError
from wrt.loader import load_scene, parse_scene

MESHES = EXAMPLES / "meshes"

GOOD = GOOD_SCENE


def mesh_scene(file):
    return GOOD + f'\n[[shape]]\ntype = "mesh"\nfile = "{file}"\n'


def run_bad(tmp_path, capsys, text, *fragments, extra_args=(), scene_bytes=None, names_scene=True):
    """Write the scene, run `wrt render` on it, check exit 2, one error line with every fragment
    (and the scene file's path, unless the culprit is a command-line option), no output."""
    scene = tmp_path / "scene.toml"
    if scene_bytes is not None:
        scene.write_bytes(scene_bytes)
    else:
        scene.write_text(text)
    before = set(os.listdir(tmp_path))
    out = tmp_path / "out.exr"
    assert main(["render", str(scene), "-o", str(out), *extra_args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("wrt: error: ") and err.count("\n") == 1, err
    for fragment in ((str(scene),) if names_scene else ()) + fragments:
        assert fragment in err, (fragment, err)
    assert set(os.listdir(tmp_path)) == before  # no output, no temporary file
    return err


# --- malformed files and wrong types ---------------------------------------------------------------

MALFORMED = [
    ("unclosed table header", GOOD.replace("[camera]", "[camera"), "not valid TOML"),
    ("duplicate key", GOOD.replace("height = 16", "height = 16\nheight = 17"), "not valid TOML"),
    ("unterminated string", GOOD.replace('name = "red"', 'name = "red'), "not valid TOML"),
    ("table defined twice", GOOD + "\n[camera]\nfov = 30\n", "not valid TOML"),
]


@pytest.mark.parametrize("text, problem", [m[1:] for m in MALFORMED], ids=[m[0] for m in MALFORMED])
def test_malformed_toml(tmp_path, capsys, text, problem):
    run_bad(tmp_path, capsys, text, problem)


@pytest.mark.parametrize(
    "data", [b"\xff\xfe\x00binary\x00", bytes(range(256)), b"\x00" * 64], ids=["utf16-ish", "all bytes", "zeros"]
)
def test_binary_file_is_not_toml(tmp_path, capsys, data):
    run_bad(tmp_path, capsys, None, "not valid TOML", scene_bytes=data)


WRONG = [
    (
        "camera as a value",
        'camera = "front"\n' + GOOD.replace("[camera]\norigin = [0, 0, 5]\nlook_at = [0, 0, 0]", ""),
        "camera",
        "must be a table",
    ),
    ("shape as a table", GOOD.replace("[[shape]]", "[shape]"), "shape", "array of tables"),
    (
        "vector of strings",
        GOOD.replace("origin = [0, 0, 5]", 'origin = ["0", "0", "5"]'),
        "camera.origin = ['0', '0', '5']",
        "3 numbers",
    ),
    ("boolean as number", GOOD.replace("radius = 1.0", "radius = true"), "shape[0].radius = True", "must be a number"),
    (
        "float where an integer is needed",
        GOOD.replace("width = 24", "width = 24.5"),
        "render.width = 24.5",
        "must be an integer",
    ),
    ("date as number", GOOD.replace("radius = 1.0", "radius = 1979-05-27"), "shape[0].radius", "must be a number"),
    ("nested vector", GOOD.replace("center = [0, 0, 0]", "center = [[0, 0, 0]]"), "shape[0].center", "3 numbers"),
    (
        "material name as number",
        GOOD.replace('material = "red"', "material = 3"),
        "shape[0].material = 3",
        "no [[material]]",
    ),
    ("negative radius", GOOD.replace("radius = 1.0", "radius = -0.5"), "shape[0].radius = -0.5", "must be in (0, inf]"),
    ("zero radius", GOOD.replace("radius = 1.0", "radius = 0"), "shape[0].radius = 0", "must be in (0, inf]"),
    ("infinite radius", GOOD.replace("radius = 1.0", "radius = inf"), "shape[0].radius = inf", "must be finite"),
    ("nan in a vector", GOOD.replace("look_at = [0, 0, 0]", "look_at = [0, nan, 0]"), "camera.look_at", "finite"),
    ("inf in a vector", GOOD.replace("center = [0, 0, 0]", "center = [0, 0, -inf]"), "shape[0].center", "finite"),
    (
        "huge integer",
        GOOD.replace("width = 24", "width = 99999999999999999999999"),
        "render.width = 99999999999999999999999",
        "must be in [1, 16384]",
    ),
    (
        "huge integer as a number",
        GOOD.replace("radius = 1.0", "radius = 1" + "0" * 40),
        "shape[0].radius = 1" + "0" * 40,
        "float32",
    ),
    ("float beyond float64", GOOD.replace("radius = 1.0", "radius = 1e400"), "shape[0].radius = inf", "must be finite"),
    (
        "zero up vector",
        GOOD.replace("look_at = [0, 0, 0]", "look_at = [0, 0, 0]\nup = [0, 0, 0]"),
        "camera.up = [0, 0, 0]",
        "zero vector",
    ),
    (
        "zero spot direction",
        GOOD + '[[light]]\ntype = "spot"\nposition = [0, 1, 0]\ndirection = [0, 0, 0]\nintensity = [1, 1, 1]\n',
        "light[0].direction = [0, 0, 0]",
        "zero vector",
    ),
    (
        "camera beyond float range",
        GOOD.replace("origin = [0, 0, 5]", "origin = [1e308, 1e308, 1e308]").replace(
            "look_at = [0, 0, 0]", "look_at = [-1e308, -1e308, -1e308]"
        ),
        "camera",
        "float32",
    ),
    (
        "sphere beyond float32",
        GOOD.replace("center = [0, 0, 0]", "center = [1e39, 0, 0]"),
        "shape[0].center",
        "float32",
    ),
    ("radius beyond float32", GOOD.replace("radius = 1.0", "radius = 1e39"), "shape[0].radius = 1e+39", "float32"),
]


@pytest.mark.parametrize("text, where, problem", [w[1:] for w in WRONG], ids=[w[0] for w in WRONG])
def test_wrong_types_and_values(tmp_path, capsys, text, where, problem):
    run_bad(tmp_path, capsys, text, where, problem)


@pytest.mark.parametrize(
    "args, where",
    [
        (["--width", "0"], "width = 0"),
        (["--height", "-3"], "height = -3"),
        (["--width", "1000000"], "width = 1000000"),
        (["--spp", "0"], "spp = 0"),
        (["--max-depth", "0"], "max_depth = 0"),
    ],
    ids=["width 0", "negative height", "width 10^6", "spp 0", "max_depth 0"],
)
def test_absurd_sizes_on_the_command_line(tmp_path, capsys, args, where):
    run_bad(tmp_path, capsys, GOOD, "command line", where, "must be in", extra_args=args, names_scene=False)


# --- meshes -----------------------------------------------------------------------------------------


def bad_mesh(tmp_path, name, data):
    path = tmp_path / name
    path.write_bytes(data if isinstance(data, bytes) else data.encode())
    return name


KNOT = (MESHES / "torus_knot.ply").read_bytes()
CUBE_STL = (MESHES / "cube.stl").read_bytes()
BAD_MESHES = [
    ("empty ply", "empty.ply", b"", "not a readable mesh"),
    ("empty obj", "empty.obj", b"", "empty mesh"),
    ("truncated ply", "cut.ply", KNOT[: len(KNOT) // 2], "truncated"),
    ("truncated stl", "cut.stl", CUBE_STL[: len(CUBE_STL) - 30], "not a readable mesh"),
    ("image renamed", "photo.obj", b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 8, "empty mesh"),
    ("text as ply", "notes.ply", "these are my notes\n", "does not start with 'ply'"),
    ("unsupported format", "mesh.blend", b"BLENDER", "unsupported mesh format '.blend'"),
    ("out-of-range index", "bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "out of range for 3 vertices"),
    (
        "negative index in ply",
        "neg.ply",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face "
        "1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 -5\n",
        "out of range",
    ),
    ("nan vertex", "nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "NaN or infinite"),
    ("vertex beyond float32", "big.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n", "float32"),
]


@pytest.mark.parametrize("name, data, problem", [b[1:] for b in BAD_MESHES], ids=[b[0] for b in BAD_MESHES])
def test_bad_mesh_files(tmp_path, capsys, name, data, problem):
    file = bad_mesh(tmp_path, name, data)
    run_bad(tmp_path, capsys, mesh_scene(file), f"shape[1].file = '{file}'", problem)


def test_truncated_legacy_vtk_is_not_loaded_partially(tmp_path, capsys):
    """VTK's legacy reader only warns on a file cut in its attribute data, and returns what it read."""
    import pyvista as pv

    full = tmp_path / "full.vtk"
    pv.Sphere().save(full)
    data = full.read_bytes()
    full.unlink()
    file = bad_mesh(tmp_path, "cut.vtk", data[: int(len(data) * 0.9)])
    run_bad(tmp_path, capsys, mesh_scene(file), "shape[1].file = 'cut.vtk'", "not a readable mesh")


def test_missing_and_directory_mesh(tmp_path, capsys):
    run_bad(tmp_path, capsys, mesh_scene("nowhere/none.obj"), "shape[1].file = 'nowhere/none.obj'", "no such mesh file")
    (tmp_path / "dir.obj").mkdir()
    run_bad(tmp_path, capsys, mesh_scene("dir.obj"), "shape[1].file = 'dir.obj'", "is a directory")


# --- memory -----------------------------------------------------------------------------------------


def test_image_too_big_for_memory_is_refused_up_front(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(wrt.renderer, "available_memory", lambda: 100 * 2**20)
    err = run_bad(
        tmp_path,
        capsys,
        GOOD,
        "render.width x height = 4000 x 3000",
        "needs about 1.8 GiB of host memory",
        "only 0.1 GiB available",
        extra_args=["--width", "4000", "--height", "3000"],
    )
    assert "64 B/pixel" in err


def test_memory_estimate_matches_the_film():
    """The estimate's film share is what the renderer allocates: 16 float32/int32 values per pixel
    (RGB, its running sum, the sum of squared luminances, the rejected-sample count, and the AOVs)."""
    scene = wrt.parse_scene(
        {"camera": {"origin": [0, 0, 5], "look_at": [0, 0, 0]}, "render": {"width": 8, "height": 4}}
    )
    device_scene = wrt.renderer.prepare(scene, wp.get_device("cpu"))
    film = sum(getattr(device_scene.film, name).capacity for name in Film.vars)
    assert film == 8 * 4 * wrt.renderer.FILM_BYTES_PER_PIXEL


def test_render_api_refuses_too(monkeypatch):
    monkeypatch.setattr(wrt.renderer, "available_memory", lambda: 2**20)
    scene = wrt.parse_scene(
        {"camera": {"origin": [0, 0, 5], "look_at": [0, 0, 0]}, "render": {"width": 1000, "height": 1000}},
        file="api.toml",
    )
    with pytest.raises(WrtError, match=r"api.toml: render.width x height = 1000 x 1000: needs about 0.2 GiB"):
        wrt.render(scene)


# --- fuzzing the loader -----------------------------------------------------------------------------

FUZZ_DOC = {
    "render": {
        "width": 8,
        "height": 6,
        "spp": 2,
        "integrator": "whitted",
        "max_depth": 3,
        "background": [0.1, 0.1, 0.1],
    },
    "camera": {"origin": [0.0, 1.0, 4.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov": 40.0},
    "material": [
        {"name": "red", "albedo": [0.8, 0.1, 0.1]},
        {"name": "glass", "type": "dielectric", "ior": 1.5, "transmittance": [0.9, 0.9, 0.9], "priority": 1},
        {"name": "shiny", "type": "phong", "albedo": [0.3, 0.3, 0.3], "specular": [0.5, 0.5, 0.5], "exponent": 20.0},
    ],
    "shape": [
        {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0, "material": "red"},
        {"type": "plane", "point": [0.0, -1.0, 0.0], "normal": [0.0, 1.0, 0.0]},
        {"type": "triangle", "vertices": [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], "material": "glass"},
        {"type": "polygon", "vertices": [[0.0, 0.0, -1.0], [1.0, 0.0, -1.0], [1.0, 1.0, -1.0], [0.0, 1.0, -1.0]]},
        {
            "type": "mesh",
            "file": "tetra.obj",
            "transform": {"translate": [1.0, 0.0, 0.0], "scale": 0.5, "rotate": [0.0, 30.0, 0.0]},
            "material": "shiny",
        },
    ],
    "light": [
        {"type": "point", "position": [0.0, 3.0, 0.0], "intensity": [5.0, 5.0, 5.0]},
        {
            "type": "spot",
            "position": [0.0, 3.0, 1.0],
            "direction": [0.0, -1.0, 0.0],
            "intensity": [1.0, 1.0, 1.0],
            "cutoff_angle": 30.0,
        },
    ],
}

scalars = st.one_of(
    st.booleans(),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from(
        [
            0,
            -1,
            1,
            0.0,
            -0.0,
            1e-45,
            1e39,
            1e308,
            16384,
            16385,
            2**31,
            "",
            "default",
            "mesh",
            "sphere",
            "dielectric",
            "a\x00b",
            "../../etc/passwd",
            1e-40,  # denormal (issue 13: a look_at a denormal away from the origin)
            -5e-324,
            1e18,  # the loader's number limit, and just past it
            1.0000001e18,
            3e38,
            "\x1b[31m\x07",  # terminal control characters
        ]
    ),
    st.text(max_size=12),
    st.dates(),
)
toml_values = st.recursive(
    scalars,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=3),
    max_leaves=8,
)


def paths(doc, prefix=()):
    """Every (path, value) inside a nested document of dicts and lists."""
    yield prefix, doc
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from paths(v, prefix + (i,))


@st.composite
def mutated_scenes(draw):
    doc = copy.deepcopy(FUZZ_DOC)
    for _ in range(draw(st.integers(1, 4))):
        spots = list(paths(doc))
        path, value = draw(st.sampled_from(spots[1:]))
        parent = doc
        for key in path[:-1]:
            parent = parent[key]
        action = draw(st.sampled_from(["replace", "delete", "add", "wrap"]))
        if action == "replace":
            parent[path[-1]] = draw(toml_values)
        elif action == "delete":
            del parent[path[-1]]
        elif action == "add" and isinstance(value, dict):
            value[draw(st.text(max_size=8))] = draw(toml_values)
        elif action == "wrap":
            parent[path[-1]] = [value]
    return doc


def assert_clean(load):
    """A clean load or a one-line WrtError; anything else (a traceback) fails the test."""
    try:
        scene = load()
    except WrtError as e:
        assert str(e) and "\n" not in str(e)
        return None
    assert isinstance(scene, wrt.scene.Scene)
    return scene


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(doc=mutated_scenes())
def test_fuzz_mutated_scene_documents(doc):
    scene = assert_clean(lambda: parse_scene(doc, file="fuzz.toml", scene_dir=str(MESHES)))
    if scene is not None:  # whatever loads is usable: finite camera, and it renders a finite image
        assert all(math.isfinite(c) for c in (*scene.camera.origin, *scene.camera.look_at, scene.camera.fov))
        small = wrt.loader.override_render(scene, width=4, height=3, spp=1)
        assert np.isfinite(wrt.render(small, specialize=False).rgb).all()


GOOD_TEXT = (EXAMPLES / "showcase.toml").read_text().replace("torus_knot.ply", "tetra.obj")


@st.composite
def mutated_texts(draw):
    text = GOOD_TEXT
    for _ in range(draw(st.integers(1, 3))):
        i = draw(st.integers(0, len(text)))
        j = draw(st.integers(i, min(len(text), i + 40)))
        text = (
            text[:i]
            + draw(
                st.sampled_from(
                    ["", "[", "]", "=", '"', "\n", "nan", "-", "[[shape]]\n", "type = ", "0", "1e400", "\x00"]
                    + ["\ufeff", "\x1b", "\x07", "1e-40", "3e38", "[" * 3000, "{a=" * 2000]  # issue 13
                )
                | st.text(max_size=6)
            )
            + text[j:]
        )
    return text


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(text=mutated_texts())
def test_fuzz_mutated_scene_files(text):
    folder = tempfile.mkdtemp()
    try:
        os.makedirs(os.path.join(folder, "meshes"))
        shutil.copy(MESHES / "tetra.obj", os.path.join(folder, "meshes", "tetra.obj"))
        path = os.path.join(folder, "scene.toml")
        with open(path, "w", encoding="utf-8", errors="surrogatepass") as f:
            f.write(text)
        assert_clean(lambda: load_scene(path))
    finally:
        shutil.rmtree(folder)


# --- output paths, checked before the render (issue 13) ---------------------------------------------


def test_output_paths_that_cannot_be_written_are_refused_before_rendering(tmp_path, capsys, monkeypatch):
    """A folder, a missing folder, the scene itself, a name over 255 bytes: one line, exit 2,
    and no render started (the renderer is never called)."""
    monkeypatch.setattr(wrt.renderer, "render", lambda *a, **k: pytest.fail("rendered before checking -o"))
    scene = tmp_path / "scene.toml"
    scene.write_text(GOOD)
    (tmp_path / "folder.exr").mkdir()
    cases = [
        (tmp_path / "folder.exr", "is a folder"),
        (tmp_path / "nowhere" / "out.exr", "does not exist"),
        (tmp_path / ("x" * 260 + ".exr"), "longer than 255 bytes"),
    ]
    for out, problem in cases:
        assert main(["render", str(scene), "-o", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.startswith("wrt: error: ") and err.count("\n") == 1 and problem in err, err
    os.symlink(scene, tmp_path / "scene.exr")  # the scene under an image's name
    assert main(["render", str(scene), "-o", str(tmp_path / "scene.exr")]) == 2
    assert "refusing to overwrite" in capsys.readouterr().err
    assert scene.read_text() == GOOD


def test_long_names_and_file_modes_survive_the_atomic_write(tmp_path):
    """A 250-byte name is valid even though its temporary name would not be; a replaced file
    keeps its permissions (0600 stays 0600)."""
    scene = tmp_path / "scene.toml"
    scene.write_text(GOOD)
    out = tmp_path / ("y" * 246 + ".exr")
    assert main(["render", str(scene), "-o", str(out)]) == 0 and out.exists()
    os.chmod(out, 0o600)
    assert main(["render", str(scene), "-o", str(out)]) == 0
    assert os.stat(out).st_mode & 0o777 == 0o600
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporary left


def test_overflowing_samples_are_counted_and_never_written(tmp_path, capsys, monkeypatch):
    """Products that overflow float32 (radiance 3e38 from a huge area light; the loader refuses
    such a file, so the scene is built past it): the samples are dropped and counted, the image
    stays finite, and `wrt render` says how many."""
    scene = tmp_path / "hot.toml"
    scene.write_text(
        '[render]\nwidth = 16\nheight = 16\nspp = 4\nintegrator = "path"\nmax_depth = 2\n\n'
        "[camera]\norigin = [0.0, 0.3, 3.0]\nlook_at = [0.0, 0.0, 0.0]\n\n"
        '[[shape]]\ntype = "plane"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\n\n'
        '[[light]]\ntype = "area"\ncorner = [-50.0, 0.5, -50.0]\nedge_u = [100.0, 0.0, 0.0]\n'
        "edge_v = [0.0, 0.0, 100.0]\nradiance = [1.0, 1.0, 1.0]\n"
    )
    parsed = load_scene(scene)
    hot = dataclasses.replace(parsed, lights=(dataclasses.replace(parsed.lights[0], radiance=(3.0e38,) * 3),))
    result = wrt.render(hot)
    assert result.rejected_samples > 0 and np.isfinite(result.rgb).all()
    monkeypatch.setattr(wrt.loader, "load_scene", lambda *a, **k: hot)
    assert main(["render", str(scene), "-o", str(tmp_path / "hot.exr")]) == 0
    assert f"{result.rejected_samples} samples were NaN or Inf" in capsys.readouterr().err
