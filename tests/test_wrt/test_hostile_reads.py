"""What wrt reads, read as a hostile user writes it: files that never end or block (a FIFO, a
device, a file larger than wrt reads), an include bomb, files whose content must not reach an
error message, a binary STL whose triangle count lies, and Mitsuba XML that Mitsuba refuses.

Every refusal: one line naming the file (for XML the line and the element too), exit code 2,
no traceback, no output, and at most ``wrt.errors.MAX_QUOTED`` characters of the file's content.
"""

import contextlib
import os
import string
import struct
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import GOOD_SCENE
from hypothesis import given
from hypothesis import strategies as st
from test_hostile_files import FUZZ, FUZZ_CLI, render
from wrt_harness.mitsuba_peer import mitsuba_available

import wrt.files
import wrt.meshio
import wrt.mitsuba.xml
from wrt.errors import MAX_QUOTED, MeshFileError, WrtError
from wrt.imageio import write_image
from wrt.loader import load_scene
from wrt.meshio import load_mesh
from wrt.mitsuba import load_mitsuba

MITSUBA, MITSUBA_REASON = mitsuba_available()
needs_mitsuba = pytest.mark.skipif(not MITSUBA, reason=MITSUBA_REASON)

SENSOR = (
    '<sensor type="perspective"><film type="hdrfilm"><integer name="width" value="4"/>'
    '<integer name="height" value="3"/></film></sensor>'
)
TRIANGLE_PLY = (
    b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    b"element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
)
TRIANGLE_OBJ = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
TRIANGLE_STL = (
    b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
    b"endloop\nendfacet\nendsolid t\n"
)
TRIANGLE_VTK = (
    b"# vtk DataFile Version 3.0\nt\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0 0 0 1 0\n"
    b"POLYGONS 1 4\n3 0 1 2\n"
)
VTM = (
    '<?xml version="1.0"?>\n<VTKFile type="vtkMultiBlockDataSet" version="1.0">\n<vtkMultiBlockDataSet>\n'
    '<DataSet index="0" file="{}"/>\n</vtkMultiBlockDataSet>\n</VTKFile>\n'
)
SPECTRUM = b"400 0.5\n700 0.5\n"
SPHERE = '<shape type="sphere">{}</shape>'
DIFFUSE = SPHERE.format('<bsdf type="diffuse">{}</bsdf>')
TRANSFORM = SPHERE.format('<transform name="to_world">{}</transform>')


def xml(body: str) -> str:
    """A Mitsuba scene whose ``<scene>`` (line 1) holds ``body`` from line 2 on."""
    return f'<scene version="3.0.0">\n{textwrap.dedent(body).strip()}\n</scene>\n'


def toml_mesh(file: str, smooth: bool = False) -> str:
    shading = 'shading = "smooth"\n' if smooth else ""
    return f'[camera]\norigin = [0, 0, 5]\nlook_at = [0, 0, 0]\n\n[[shape]]\ntype = "mesh"\nfile = "{file}"\n{shading}'


def toml_texture(file: str) -> str:
    return GOOD_SCENE.replace("albedo = [0.8, 0.1, 0.1]", f'albedo = {{ texture = "bitmap", file = "{file}" }}')


def toml_envmap(file: str) -> str:
    return GOOD_SCENE.replace("height = 16", 'height = 16\nintegrator = "path"') + (
        f'\n[[light]]\ntype = "environment"\nfile = "{file}"\n'
    )


def tiny_image(path: Path) -> bytes:
    write_image(path, np.full((2, 4, 3), 0.5, dtype=np.float32))
    data = path.read_bytes()
    path.unlink()
    return data


def vtp_bytes(folder: Path) -> bytes:
    import pyvista as pv

    path = folder / "piece.vtp"
    pv.PolyData(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), faces=[3, 0, 1, 2]).save(path)
    data = path.read_bytes()
    path.unlink()
    return data


# --- 1. what is read is a regular file of a bounded size, checked before it is read --------------

# reader: (the file it reads, its valid content, the scene that makes wrt read it, that scene's name)
READERS = {
    "TOML scene": ("scene.toml", lambda d: GOOD_SCENE.encode(), None, "scene.toml"),
    "Mitsuba scene": ("scene.xml", lambda d: xml('<shape type="sphere"/>').encode(), None, "scene.xml"),
    "included fragment": (
        "fragment.xml",
        lambda d: xml('<shape type="sphere"/>').encode(),
        xml('<include filename="fragment.xml"/>'),
        "scene.xml",
    ),
    "spectrum file": (
        "warm.spd",
        lambda d: SPECTRUM,
        xml(DIFFUSE.format('<spectrum name="reflectance" filename="warm.spd"/>')),
        "scene.xml",
    ),
    "PLY mesh": ("mesh.ply", lambda d: TRIANGLE_PLY, toml_mesh("mesh.ply"), "scene.toml"),
    "OBJ mesh (smooth)": ("mesh.obj", lambda d: TRIANGLE_OBJ, toml_mesh("mesh.obj", smooth=True), "scene.toml"),
    "OBJ mesh (VTK)": ("mesh.obj", lambda d: TRIANGLE_OBJ, toml_mesh("mesh.obj"), "scene.toml"),
    "STL mesh": ("mesh.stl", lambda d: TRIANGLE_STL, toml_mesh("mesh.stl"), "scene.toml"),
    "VTK mesh": ("mesh.vtk", lambda d: TRIANGLE_VTK, toml_mesh("mesh.vtk"), "scene.toml"),
    "multiblock piece": ("piece.vtp", vtp_bytes, None, "scene.toml"),  # scene and .vtm written below
    "texture": ("image.png", lambda d: tiny_image(d / "x.png"), toml_texture("image.png"), "scene.toml"),
    "environment map": ("sky.exr", lambda d: tiny_image(d / "x.exr"), toml_envmap("sky.exr"), "scene.toml"),
}


def write_scene(folder: Path, reader: str) -> Path:
    """The scene that makes wrt read the file of ``reader`` (itself, for a scene file)."""
    name, _, scene, scene_name = READERS[reader]
    if reader == "multiblock piece":
        (folder / "mesh.vtm").write_text(VTM.format(name))
        scene = toml_mesh("mesh.vtm")
    if scene is not None:
        (folder / scene_name).write_text(scene)
    return folder / scene_name


@contextlib.contextmanager
def serving_fifo(path: Path, data: bytes):
    """``path`` made a FIFO that a writer thread feeds ``data`` to each time it is opened for
    reading (so that a reader that opens it, even twice, does not block: it reads a valid file)."""
    os.mkfifo(path)
    done = threading.Event()

    def serve():
        while not done.is_set():
            with contextlib.suppress(OSError):
                with open(path, "wb") as f:  # blocks until a reader opens the FIFO
                    if not done.is_set():
                        f.write(data)

    writer = threading.Thread(target=serve, daemon=True)
    writer.start()
    try:
        yield path
    finally:
        done.set()
        deadline = time.monotonic() + 10
        while writer.is_alive() and time.monotonic() < deadline:  # release a writer waiting for a reader
            with contextlib.suppress(OSError):
                fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
                writer.join(0.05)
                os.close(fd)


def assert_refused(scene: Path, *fragments) -> str:
    with pytest.raises(WrtError) as caught:
        load_scene(scene)
    message = str(caught.value)
    assert "\n" not in message, message
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    return message


@pytest.mark.parametrize("reader", READERS)
def test_a_fifo_is_refused_before_it_is_read(tmp_path, reader):
    """A FIFO blocks a reader until a writer comes, and a writer may never end: it is refused by
    its kind, before wrt opens it for reading (here a writer waits with a valid file)."""
    name, content, _, _ = READERS[reader]
    data = content(tmp_path)
    scene = write_scene(tmp_path, reader)
    with serving_fifo(tmp_path / name, data):
        assert_refused(scene, name, "is a FIFO")


@pytest.mark.parametrize("reader", READERS)
def test_a_device_is_refused_before_it_is_read(tmp_path, reader):
    """A device (``/dev/zero`` never ends; ``/dev/null`` here, reached through a link named like
    the file) is refused by its kind."""
    name, _, _, _ = READERS[reader]
    scene = write_scene(tmp_path, reader)
    (tmp_path / name).symlink_to("/dev/null")
    assert_refused(scene, name, "is a device")


@pytest.mark.parametrize("reader", ["TOML scene", "Mitsuba scene", "included fragment", "spectrum file"])
def test_a_text_file_larger_than_wrt_reads_is_refused_by_its_size(tmp_path, reader):
    """A text input (scene, fragment, spectrum) of more than ``MAX_TEXT_BYTES`` is refused by its
    size, before a byte of it is read (a sparse file: it takes no space)."""
    name, content, _, _ = READERS[reader]
    scene = write_scene(tmp_path, reader)
    with open(tmp_path / name, "wb") as f:
        f.write(content(tmp_path))
        f.truncate(wrt.files.MAX_TEXT_BYTES + 1)
    assert_refused(scene, name, f"larger than the {wrt.files.MAX_TEXT_BYTES} bytes wrt reads")


@pytest.mark.parametrize("reader", ["PLY mesh", "OBJ mesh (smooth)", "OBJ mesh (VTK)", "STL mesh", "multiblock piece"])
def test_a_mesh_larger_than_wrt_reads_is_refused_by_its_size(tmp_path, monkeypatch, reader):
    """A mesh larger than ``MAX_MESH_BYTES`` (16 GiB; here lowered to 16 bytes) is refused by its
    size, whichever reader would read it."""
    name, content, _, _ = READERS[reader]
    scene = write_scene(tmp_path, reader)
    vtm = tmp_path / "mesh.vtm"  # read, within the bound, for the piece it names
    monkeypatch.setattr(wrt.meshio, "MAX_MESH_BYTES", vtm.stat().st_size if vtm.exists() else 16, raising=False)
    (tmp_path / name).write_bytes(content(tmp_path))
    assert_refused(scene, name, "bytes wrt reads")


def test_the_cli_refuses_a_fifo_scene_in_one_line(tmp_path, capsys):
    scene = tmp_path / "fifo.toml"
    with serving_fifo(scene, GOOD_SCENE.encode()):
        code, lines = render(capsys, scene)
    assert code == 2 and str(scene) in lines[0] and "is a FIFO" in lines[0], lines


def test_proc_files_are_read_bounded_and_the_regular_inputs_still_load(tmp_path):
    """``/proc`` files report a size of 0 but are read within the bound (here a scene file that is
    not TOML); every reader still reads its valid file."""
    assert_refused(Path("/proc/self/status"), "/proc/self/status", "not valid TOML")
    for reader, (name, content, _, _) in READERS.items():
        folder = tmp_path / reader.replace(" ", "_").replace("(", "").replace(")", "")
        folder.mkdir()
        scene = write_scene(folder, reader)
        (folder / name).write_bytes(content(folder))
        assert load_scene(scene).shapes, reader


# --- 2. an include bomb is refused before it is expanded ------------------------------------------


def include_bomb(folder: Path, levels: int = 7, fanout: int = 10) -> Path:
    """Fragments f0 .. f{levels-1}, each including the next ``fanout`` times, the last holding
    ``fanout`` spheres: ``fanout ** levels`` shapes from a few hundred bytes, and no loop."""
    for level in range(levels):
        inner = f'<include filename="f{level + 1}.xml"/>' if level + 1 < levels else '<shape type="sphere"/>'
        (folder / f"f{level}.xml").write_text(xml(inner * fanout))
    scene = folder / "bomb.xml"
    scene.write_text(xml('<include filename="f0.xml"/>'))
    return scene


def test_an_include_bomb_is_one_line_naming_the_file_and_the_bound(tmp_path, capsys):
    """10^7 elements from seven 250-byte files: refused as soon as the fragments are read (their
    expansions are shared, and counted, before any is built)."""
    scene = include_bomb(tmp_path)
    code, lines = render(capsys, scene)
    assert code == 2, lines
    assert f"{scene}:2: <include>" in lines[0] and str(wrt.mitsuba.xml.MAX_ELEMENTS) in lines[0], lines


def test_a_wide_include_tree_below_the_bound_converts_every_element(tmp_path):
    """Shared expansions are copied into place: a fragment included 3 x 3 times gives nine
    shapes, each its own element (distinct sources), and an id in a fragment included twice is
    a duplicate id, as in Mitsuba."""
    scene = include_bomb(tmp_path, levels=2, fanout=3)
    doc, _ = load_mitsuba(scene)
    assert [s["type"] for s in doc["shape"]] == ["sphere"] * 9
    (tmp_path / "named.xml").write_text(xml('<bsdf type="diffuse" id="grey"/>'))
    twice = tmp_path / "twice.xml"
    twice.write_text(xml('<include filename="named.xml"/>\n<include filename="named.xml"/>'))
    with pytest.raises(WrtError, match=r"named\.xml:2: <bsdf type=\"diffuse\" id=\"grey\">: id 'grey' is already"):
        load_mitsuba(twice)


def test_an_include_loop_through_a_shared_fragment_is_still_a_loop(tmp_path):
    """a includes b twice; b includes c; c includes b: the second include of b reuses its
    expansion, which must not hide the loop (refused at the first)."""
    (tmp_path / "b.xml").write_text(xml('<include filename="c.xml"/>'))
    (tmp_path / "c.xml").write_text(xml('<include filename="b.xml"/>'))
    scene = tmp_path / "a.xml"
    scene.write_text(xml('<include filename="b.xml"/>\n<include filename="b.xml"/>'))
    with pytest.raises(WrtError, match="include loop: a.xml > b.xml > c.xml > b.xml"):
        load_mitsuba(scene)


# --- 3. a file's content never reaches a message beyond a short token ----------------------------

SECRETS = st.text(string.ascii_letters + string.digits, min_size=40, max_size=300).map(lambda s: "Zq" + s)


def leaked(message: str, secret: str) -> str | None:
    """A piece of ``secret`` longer than ``MAX_QUOTED`` characters that ``message`` holds, in any
    case (VTK lowercases what it quotes), or None."""
    secret, message = secret.lower(), message.lower()
    for i in range(len(secret) - MAX_QUOTED):
        if secret[i : i + MAX_QUOTED + 1] in message:
            return secret[i : i + MAX_QUOTED + 1]
    return None


def _spd(body):
    return {
        "scene.xml": xml(
            '<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" filename="s.spd"/></bsdf></shape>'
        ),
        "s.spd": body,
    }


def _xml(body):
    return {"scene.xml": xml(SENSOR + body)}


def _ply(header_extra="", body="0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", fmt="ascii", vertex_type="float"):
    return {
        "scene.toml": toml_mesh("m.ply"),
        "m.ply": f"ply\nformat {fmt} 1.0\n{header_extra}element vertex 3\nproperty {vertex_type} x\n"
        "property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n"
        f"end_header\n{body}",
    }


LEAKS = {
    # TOML: a value, a key, a list, the names listed as known, a table declared twice, a comment
    "toml string value": lambda s: {"scene.toml": GOOD_SCENE.replace('type = "sphere"', f'type = "{s}"')},
    "toml literal string": lambda s: {"scene.toml": GOOD_SCENE.replace('type = "sphere"', f"type = '{s}'")},
    "toml key": lambda s: {"scene.toml": GOOD_SCENE.replace("radius = 1.0", f"radius = 1.0\n{s} = 1")},
    "toml list": lambda s: {"scene.toml": GOOD_SCENE.replace("[0, 0, 5]", f'["{s}", 0, 5]')},
    "toml known names": lambda s: {
        "scene.toml": GOOD_SCENE.replace('name = "red"', f'name = "{s}"').replace('material = "red"', 'material = "x"')
    },
    "toml table twice": lambda s: {"scene.toml": GOOD_SCENE + f"[{s}]\n[{s}]\n"},
    "toml comment": lambda s: {"scene.toml": f"# {s}\n" + GOOD_SCENE + "x = [1,\n"},
    # Mitsuba XML: a value, a type, a tag, an attribute, an id, a $parameter, a name, an include
    "xml value": lambda s: _xml(f'<shape type="sphere"><float name="radius" value="{s}"/></shape>'),
    "xml numbers": lambda s: _xml(f'<shape type="sphere"><point name="center" value="1 {s} 2"/></shape>'),
    "xml type": lambda s: _xml(f'<shape type="{s}"/>'),
    "xml tag": lambda s: _xml(f'<shape type="sphere"><{s}/></shape>'),
    "xml attribute": lambda s: _xml(f'<shape type="sphere" {s}="1"/>'),
    "xml ref": lambda s: _xml(f'<shape type="sphere"><ref id="{s}"/></shape>'),
    "xml parameter": lambda s: _xml(f'<shape type="sphere"><float name="radius" value="${s}"/></shape>'),
    "xml ior": lambda s: _xml(
        f'<shape type="sphere"><bsdf type="dielectric"><string name="int_ior" value="{s}"/></bsdf></shape>'
    ),
    "xml unknown parameter": lambda s: _xml(f'<shape type="sphere"><float name="{s}" value="1"/></shape>'),
    "xml version": lambda s: {"scene.xml": f'<scene version="{s}"><shape type="sphere"/></scene>'},
    "xml include": lambda s: _xml(f'<include filename="{s}.xml"/>'),
    "xml duplicate id": lambda s: _xml(f'<bsdf type="diffuse" id="{s}"/><bsdf type="diffuse" id="{s}"/>'),
    # spectrum files: a line that is no pair (a line of /etc/shadow), a value
    "spd line": lambda s: _spd(f"400 0.5\n{s}\n"),
    "spd shadow line": lambda s: _spd(f"root:$6${s}:19000:0:99999:7:::\n"),
    "spd value": lambda s: _spd(f"400 {s}\n500 1\n"),
    # PLY header and body, OBJ lines, VTK's messages, multiblock pieces
    "ply header line": lambda s: _ply(header_extra=f"element {s} 1 2\n"),
    "ply format": lambda s: _ply(fmt=s),
    "ply property type": lambda s: _ply(vertex_type=s),
    "ply element name": lambda s: _ply(header_extra=f"element {s} 1\n"),
    "ply body": lambda s: _ply(body=f"0 0 0\n1 {s} 0\n0 1 0\n3 0 1 2\n"),
    "obj vertex": lambda s: {"scene.toml": toml_mesh("m.obj", smooth=True), "m.obj": f"v 0 0 0\nv 1 {s} 0\n"},
    "obj face": lambda s: {"scene.toml": toml_mesh("m.obj", smooth=True), "m.obj": f"{TRIANGLE_OBJ.decode()}f 1 {s}\n"},
    "vtk keyword": lambda s: {
        "scene.toml": toml_mesh("m.vtk"),
        "m.vtk": TRIANGLE_VTK.decode().replace("POLYGONS", f"{s} 3\nPOLYGONS"),
    },
    "vtk file type": lambda s: {"scene.toml": toml_mesh("m.vtk"), "m.vtk": f"# vtk DataFile Version 3.0\nt\n{s}\n"},
    "vtm piece": lambda s: {"scene.toml": toml_mesh("m.vtm"), "m.vtm": VTM.format(f"{s}.vtp")},
    # images: OpenImageIO's messages
    "texture": lambda s: {"scene.toml": toml_texture("t.png"), "t.png": b"\x89PNG\r\n\x1a\n" + s.encode() * 3},
    "environment map": lambda s: {
        "scene.toml": toml_envmap("e.hdr"),
        "e.hdr": f"#?RADIANCE\nFORMAT={s}\n\n-Y 2 +X 2\n",
    },
}


def assert_no_leak(case: str, secret: str) -> None:
    with tempfile.TemporaryDirectory() as folder:
        files = LEAKS[case](secret)
        for name, data in files.items():
            (Path(folder) / name).write_bytes(data.encode() if isinstance(data, str) else data)
        scene = Path(folder) / next(iter(files))
        with pytest.raises(WrtError) as caught:
            load_scene(scene)
        message = str(caught.value)
        assert str(scene) in message and "\n" not in message, message
        assert leaked(message, secret) is None, (case, message)


@pytest.mark.parametrize("case", LEAKS)
def test_a_file_s_content_is_never_echoed_beyond_a_token(case):
    assert_no_leak(case, "Zq" + string.ascii_letters * 3)


@FUZZ
@given(case=st.sampled_from(sorted(LEAKS)), secret=SECRETS)
def test_fuzz_no_reader_echoes_a_long_secret(case, secret):
    assert_no_leak(case, secret)


def test_proc_self_environ_as_a_spectrum_does_not_print_the_environment(tmp_path):
    """Found by the hostile user: ``<spectrum filename="/proc/self/environ">`` printed the whole
    environment, values included. ``/proc/self/environ`` is the environment the process started
    with: a child process starts with a secret as its first variable."""
    secret = "Zq" + string.ascii_letters * 2
    scene = tmp_path / "scene.xml"
    scene.write_text(xml(DIFFUSE.format('<spectrum name="reflectance" filename="/proc/self/environ"/>')))
    code = "import sys\nfrom wrt.loader import load_scene\ntry:\n    load_scene(sys.argv[1])\nexcept Exception as e:\n"
    code += "    print(e)"
    environment = {"WRT_SECRET": secret}  # first, then what makes the child import this wrt
    environment.update({k: v for k, v in os.environ.items() if k == "PYTHONPATH"})
    child = subprocess.run(
        [sys.executable, "-c", code, str(scene)],
        env=environment,
        capture_output=True,
        text=True,
        timeout=120,
    )
    message = child.stdout.strip()
    assert child.returncode == 0 and "/proc/self/environ" in message and "\n" not in message, child
    assert leaked(message, secret) is None, message


def test_a_leaked_token_is_escaped_and_cut(tmp_path, capsys):
    """The token of a value holding control characters is escaped and cut with an ellipsis; the
    line reaching the terminal holds no raw control character."""
    scene = tmp_path / "scene.toml"
    scene.write_text(GOOD_SCENE.replace('type = "sphere"', 'type = "\\u001b[2J' + "x" * 100 + '"'))
    code, lines = render(capsys, scene)
    assert code == 2 and "shape[0].type = '\\x1b[2J" + "x" * (MAX_QUOTED - 4) + "'..." in lines[0], lines


# --- 4. a binary STL's triangle count must match its size ------------------------------------------


def binary_stl(count: int, triangles: int, header: bytes = b"\x00binary") -> bytes:
    triangle = struct.pack("<12fH", 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0)
    return header.ljust(80, b"\x00")[:80] + struct.pack("<I", count) + triangle * triangles


@FUZZ
@given(
    count=st.integers(0, 6) | st.sampled_from([2**31, 2**32 - 1]),
    triangles=st.integers(1, 5),
    header=st.sampled_from([b"\x00binary", b"solid exported by a tool that writes binary"]),
)
def test_fuzz_a_binary_stl_loads_only_when_its_count_matches_its_size(count, triangles, header):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "m.stl"
        data = binary_stl(count, triangles, header)
        path.write_bytes(data)
        if count == triangles:
            assert load_mesh(path)[1].shape == (triangles, 3)
        else:
            with pytest.raises(MeshFileError) as caught:
                load_mesh(path)
            message = str(caught.value)
            assert message.startswith(f"{path}: ") and "\n" not in message, message
            assert f"declares {count} triangle" in message and f"has {len(data)} bytes" in message, message


def test_a_lying_stl_is_one_line_and_an_ascii_stl_still_loads(tmp_path, capsys):
    (tmp_path / "m.stl").write_bytes(binary_stl(7, 2))
    scene = tmp_path / "scene.toml"
    scene.write_text(toml_mesh("m.stl"))
    code, lines = render(capsys, scene)
    assert code == 2 and "m.stl" in lines[0] and "declares 7 triangles" in lines[0] and "184 bytes" in lines[0], lines
    (tmp_path / "m.stl").write_bytes(TRIANGLE_STL)
    assert load_mesh(tmp_path / "m.stl")[1].shape == (1, 3)


# --- 5. Mitsuba XML that Mitsuba refuses is refused, with its line, element and attribute ----------

# (id, body after the sensor on line 2, Mitsuba 3.9.1 refuses it, what wrt's message names)
STRICT = [
    ("point yy", SPHERE.format('<point name="center" x="0" y="0" z="0" yy="0.5"/>'), True, "attribute 'yy'"),
    ("float foo", SPHERE.format('<float name="radius" value="1" foo="2"/>'), True, "attribute 'foo'"),
    ("float id", SPHERE.format('<float name="radius" value="1" id="r"/>'), True, "attribute 'id'"),
    ("shape foo", '<shape type="sphere" foo="1"/>', True, "attribute 'foo'"),
    ("sensor-less film foo", '<film type="hdrfilm" foo="1"/>', True, "attribute 'foo'"),
    ("transform foo", TRANSFORM.format('<translate x="1"/>').replace('to_world"', 'to_world" foo="1"'), True, "'foo'"),
    ("translate w", TRANSFORM.format('<translate x="1" w="2"/>'), True, "attribute 'w'"),
    ("translate value and x", TRANSFORM.format('<translate value="1" x="2"/>'), True, "'value' is given with"),
    ("rotate q", TRANSFORM.format('<rotate x="1" angle="3" q="2"/>'), True, "attribute 'q'"),
    ("rotate without angle", TRANSFORM.format('<rotate x="1"/>'), True, "'angle' is required"),
    ("scale q", TRANSFORM.format('<scale value="1" q="2"/>'), True, "attribute 'q'"),
    ("lookat value", TRANSFORM.format('<lookat origin="0,0,1" target="0,0,0" value="1"/>'), True, "'value'"),
    ("matrix without value", TRANSFORM.format("<matrix/>"), True, "'value' is required"),
    ("rgb q", DIFFUSE.format('<rgb name="reflectance" value="0.5" q="1"/>'), True, "attribute 'q'"),
    ("rgb without name", DIFFUSE.format('<rgb value="0.5"/>'), True, "'name' is required"),
    ("spectrum q", DIFFUSE.format('<spectrum name="reflectance" value="0.5" q="1"/>'), True, "attribute 'q'"),
    ("ref q", '<bsdf type="diffuse" id="a"/>' + SPHERE.format('<ref id="a" q="1"/>'), True, "attribute 'q'"),
    ("ref without id", SPHERE.format('<ref name="bsdf"/>'), True, "'id' is required"),
    ("default q", '<default name="x" value="1" q="2"/>' + SPHERE.format(""), True, "attribute 'q'"),
    ("boolean q", SPHERE.format('<boolean name="flip_normals" value="false" q="2"/>'), True, "attribute 'q'"),
    ("point without z", SPHERE.format('<point name="center" x="0" y="0"/>'), True, "'z' is required"),
    ("shape without type", "<shape/>", True, "'type' is required"),
    ("path inside a shape", SPHERE.format('<path value="."/>'), True, "child of its file's root"),
    ("path to no folder", '<path value="nowhere"/>', True, "no such folder 'nowhere'"),
    ("unknown element", "<foo/>", True, "<foo>: not an element"),
    ("unknown element in a shape", SPHERE.format("<foo/>"), True, "<foo>: not an element"),
    ("translate outside a transform", SPHERE.format('<translate x="1"/>'), True, "a transform operation inside"),
    ("float inside a transform", TRANSFORM.format('<float name="a" value="1"/>'), True, "not a transform operation"),
    (
        "rgb inside a float",
        SPHERE.format('<float name="radius" value="1"><rgb name="x" value="1"/></float>'),
        True,
        '<rgb name="x">: inside',
    ),
    (
        "radius twice",
        SPHERE.format('<float name="radius" value="1"/><float name="radius" value="2"/>'),
        True,
        "parameter 'radius'",
    ),
    (
        "radius float and integer",
        SPHERE.format('<float name="radius" value="1"/><integer name="radius" value="2"/>'),
        True,
        "parameter 'radius'",
    ),
    (
        "to_world twice",
        SPHERE.format('<transform name="to_world"><translate x="1"/></transform>' * 2),
        True,
        "parameter 'to_world'",
    ),
    (
        "reflectance twice",
        DIFFUSE.format('<rgb name="reflectance" value="0.5"/><rgb name="reflectance" value="0.2"/>'),
        True,
        "parameter 'reflectance'",
    ),
    (
        "texture then rgb",
        DIFFUSE.format('<texture type="checkerboard" name="reflectance"/><rgb name="reflectance" value="0.5"/>'),
        True,
        "parameter 'reflectance'",
    ),
    (
        "bsdf then ref of its name",
        '<bsdf type="diffuse" id="a"/>'
        + SPHERE.format('<bsdf type="conductor" name="bsdf"/><ref id="a" name="bsdf"/>'),
        True,
        "parameter 'bsdf'",
    ),
    (
        "film width twice",
        '<film type="hdrfilm"><integer name="width" value="4"/><integer name="width" value="5"/></film>',
        True,
        "parameter 'width'",
    ),
    # accepted by Mitsuba, and converted by wrt
    ("rotate value", TRANSFORM.format('<rotate value="0 1 0" angle="30"/>'), False, None),
    ("lookat without up", TRANSFORM.format('<lookat origin="0,0,1" target="0,0,0"/>'), False, None),
    ("empty translate", TRANSFORM.format("<translate/>"), False, None),
    ("shape name", '<shape type="sphere" name="foo"/>', False, None),
    ("point value", SPHERE.format('<point name="center" value="0 1 0"/>'), False, None),
    ("two defaults", '<default name="x" value="1"/><default name="x" value="2"/>' + SPHERE.format(""), False, None),
]


def strict_scene(folder: Path, body: str) -> Path:
    path = folder / "scene.xml"
    path.write_text(f'<scene version="3.0.0">\n{SENSOR}\n{body}\n</scene>\n')
    return path


def mitsuba_refuses(path: Path) -> bool:
    import mitsuba as mi
    from wrt_harness.mitsuba_peer import variant

    mi.set_variant(variant())
    try:
        mi.load_file(str(path))
    except Exception:  # noqa: BLE001 (any refusal of Mitsuba's)
        return True
    return False


@pytest.mark.parametrize("body, refuses, named", [c[1:] for c in STRICT], ids=[c[0] for c in STRICT])
def test_what_mitsuba_refuses_is_refused_even_approximated(tmp_path, capsys, body, refuses, named):
    """Faithful or refused: an attribute an element does not take, a required one missing, an
    element where Mitsuba takes none, a parameter given twice: refused (with --approximate too)
    naming the file, the line and the element; what Mitsuba accepts still converts."""
    path = strict_scene(tmp_path, body)
    if not refuses:
        load_mitsuba(path, approximate=True)
        return
    with pytest.raises(WrtError) as caught:
        load_mitsuba(path, approximate=True)
    message = str(caught.value)
    assert message.startswith(f"{path}:3: <") and named in message and "\n" not in message, message
    code, lines = render(capsys, path)
    assert code == 2 and lines[0] == f"wrt: error: {message}", lines


@needs_mitsuba
@pytest.mark.parametrize("body, refuses", [c[1:3] for c in STRICT], ids=[c[0] for c in STRICT])
def test_mitsuba_itself_refuses_what_the_table_says(tmp_path, body, refuses):
    assert mitsuba_refuses(strict_scene(tmp_path, body)) == refuses


def test_a_named_object_replaces_what_had_its_name_as_in_mitsuba(tmp_path):
    """Mitsuba takes the last of two objects of one name, and an object in place of an earlier
    parameter of its name; the properties and references at the top of an included file it
    ignores. wrt converts them alike."""
    both = strict_scene(tmp_path, SPHERE.format('<bsdf type="diffuse" name="b"/><bsdf type="conductor" name="b"/>'))
    assert [m["type"] for m in load_mitsuba(both)[0]["material"]] == ["mirror"]  # the conductor, not the diffuse
    texture = DIFFUSE.format('<rgb name="reflectance" value="0.5"/><texture type="checkerboard" name="reflectance"/>')
    material = load_mitsuba(strict_scene(tmp_path, texture))[0]["material"][0]
    assert material["albedo"]["texture"] == "checkerboard"
    (tmp_path / "radius.xml").write_text(xml('<float name="radius" value="7"/>\n<ref id="gold" name="bsdf"/>'))
    body = '<bsdf type="conductor" id="gold"/>' + SPHERE.format('<include filename="radius.xml"/>')
    doc, _ = load_mitsuba(strict_scene(tmp_path, body))
    assert doc["shape"][0]["radius"] == 1.0 and doc["material"][0]["type"] == "diffuse"


UNEXPECTED = ["yy", "foo", "id", "type", "value", "name", "version", "filename", "x", "angle", "as"]
ELEMENTS = [
    SPHERE.format('<point name="center" x="0" y="0" z="0"/>'),
    SPHERE.format('<float name="radius" value="1"/>'),
    SPHERE.format('<boolean name="flip_normals" value="false"/>'),
    DIFFUSE.format('<rgb name="reflectance" value="0.5"/>'),
    DIFFUSE.format('<spectrum name="reflectance" value="0.5"/>'),
    TRANSFORM.format('<translate x="1"/>'),
    TRANSFORM.format('<rotate y="1" angle="30"/>'),
    TRANSFORM.format('<scale x="2"/>'),
    TRANSFORM.format('<lookat origin="0,0,1" target="0,0,0" up="0,1,0"/>'),
    TRANSFORM.format('<matrix value="1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1"/>'),
    '<shape type="sphere"/>',
    '<emitter type="point"><point name="position" value="0 2 0"/></emitter>',
]


@st.composite
def strict_mutations(draw):
    """A small scene with one extra attribute on one element, or one parameter given twice."""
    body = draw(st.sampled_from(ELEMENTS))
    tags = [i for i, c in enumerate(body) if c == "<" and body[i + 1] != "/"]
    at = draw(st.sampled_from(tags))
    if draw(st.booleans()):
        end = body.index(">", at)
        end -= body[end - 1] == "/"
        name = draw(st.sampled_from(UNEXPECTED) | st.from_regex(r"[a-z][a-z_]{0,12}", fullmatch=True))
        if f" {name}=" in body[at:end]:
            name += "_"
        return body[:end] + f' {name}="1"' + body[end:]
    parameter = next((m for m in ("point", "float", "boolean", "rgb", "spectrum") if f"<{m} " in body), None)
    if parameter is None:
        return body
    start = body.index(f"<{parameter} ")
    element = body[start : body.index("/>", start) + 2]
    return body.replace(element, element * 2)


@FUZZ_CLI
@given(body=strict_mutations())
def test_fuzz_mitsuba_s_refusals_are_wrt_s(body):
    """Whatever Mitsuba refuses of these mutations, wrt refuses, even with --approximate, naming
    the file and line (checked against Mitsuba itself where it is installed)."""
    with tempfile.TemporaryDirectory() as folder:
        path = strict_scene(Path(folder), body)
        try:
            load_mitsuba(path, approximate=True)
            converted = True
        except WrtError as e:
            assert str(e).startswith(f"{path}:") and "\n" not in str(e), str(e)
            converted = False
        if MITSUBA and converted:
            assert not mitsuba_refuses(path), f"wrt converted what Mitsuba refuses: {body}"
