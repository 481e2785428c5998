"""Hostile input: files and command lines written to break the loader or the terminal, not by mistake.

Every refusal is the product's convention: one line ``wrt: error: ...`` naming the file (or the
option), the key and the value, exit code 2, no output file and no traceback.
"""

import argparse
import os
import re

import pytest
from conftest import GOOD_SCENE

import wrt
import wrt.rayview
import wrt.renderer
import wrt.stress
from wrt.cli import _parser, main, run_verb
from wrt.errors import SceneError, WrtError
from wrt.loader import load_scene, parse_scene

GOOD = GOOD_SCENE

BOM = b"\xef\xbb\xbf"
# C0 controls, DEL and C1 controls: none of them may reach the terminal raw (a newline ends the line)
RAW_CONTROL = re.compile("[\x00-\x09\x0b-\x1f\x7f-\x9f]")


def one_line_error(capsys, code):
    """The exit code is 2 and stderr is exactly one ``wrt: error:`` line with no raw control
    character; returns that line."""
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith("wrt: error: ") and err.count("\n") == 1 and err.endswith("\n"), err
    assert not RAW_CONTROL.search(err), repr(err)
    return err


def render_bad(tmp_path, capsys, data, *fragments, extra_args=(), scene_name="scene.toml", names_scene=True):
    """Write the scene (bytes or text), run `wrt render` on it: exit 2, one line holding every
    fragment (and the scene's path unless the culprit is an option), no output file."""
    scene = tmp_path / scene_name
    scene.write_bytes(data if isinstance(data, bytes) else data.encode())
    before = set(os.listdir(tmp_path))
    err = one_line_error(capsys, main(["render", str(scene), "-o", str(tmp_path / "out.exr"), *extra_args]))
    for fragment in ((str(scene),) if names_scene else ()) + fragments:
        assert fragment in err, (fragment, err)
    assert set(os.listdir(tmp_path)) == before  # no output, no temporary file
    return err


# --- 1. nesting deeper than the parser's recursion ------------------------------------------------


@pytest.mark.parametrize(
    "text",
    [
        "a = " + "[" * 100_000 + "]" * 100_000 + "\n",
        "a = " + "[" * 100_000 + "\n",  # unclosed as well
        "a = " + "{b = " * 5000 + "1" + "}" * 5000 + "\n",
        GOOD.replace("origin = [0, 0, 5]", "origin = " + "[" * 2000 + "]" * 2000),
    ],
    ids=["arrays", "unclosed arrays", "inline tables", "inside a camera"],
)
def test_deep_nesting_is_one_line_naming_the_file(tmp_path, capsys, text):
    render_bad(tmp_path, capsys, text, "nested too deeply")


def test_nesting_the_parser_takes_is_still_judged_by_the_loader(tmp_path, capsys):
    """300 levels parse; the loader then refuses the value (its repr stays one line)."""
    text = GOOD.replace("origin = [0, 0, 5]", "origin = " + "[" * 300 + "]" * 300)
    render_bad(tmp_path, capsys, text, "camera.origin = [[[", "3 numbers")


# --- 2. a UTF-8 byte-order mark ---------------------------------------------------------------------


def test_a_leading_byte_order_mark_is_accepted(tmp_path, capsys):
    plain, marked = tmp_path / "plain.toml", tmp_path / "marked.toml"
    plain.write_text(GOOD)
    marked.write_bytes(BOM + GOOD.encode())
    scene = load_scene(marked)
    assert scene.render == load_scene(plain).render and scene.shapes == load_scene(plain).shapes
    assert main(["render", str(marked), "-o", str(tmp_path / "out.png")]) == 0
    assert (tmp_path / "out.png").exists()


def test_only_one_byte_order_mark_is_skipped(tmp_path, capsys):
    """A second mark is text inside the file: not valid TOML, as any other stray character."""
    render_bad(tmp_path, capsys, BOM + BOM + GOOD.encode(), "not valid TOML")


# --- 3. control characters never reach the terminal -------------------------------------------------

HOSTILE = "evil\x1b[31m\x07\x7f\x9b"


def test_control_characters_in_a_missing_scene_path_are_escaped(tmp_path, capsys):
    scene = tmp_path / f"{HOSTILE}.toml"
    err = one_line_error(capsys, main(["render", str(scene), "-o", str(tmp_path / "out.exr")]))
    assert "cannot read scene file" in err and r"evil\x1b[31m\x07\x7f\x9b.toml" in err, err


def test_control_characters_in_an_output_path_are_escaped(tmp_path, capsys):
    scene = tmp_path / "scene.toml"
    scene.write_text(GOOD)
    err = one_line_error(capsys, main(["render", str(scene), "-o", str(tmp_path / f"{HOSTILE}.jpg")]))
    assert "unsupported output format" in err and r"\x1b[31m\x07" in err, err


def test_control_characters_in_values_and_keys_are_escaped(tmp_path, capsys):
    text = GOOD.replace('name = "red"', 'name = "red"\n"k\\u001b[2J" = "\\u0007"')
    err = render_bad(tmp_path, capsys, text, "material[0]", "unknown key")
    assert r"\x1b[2J" in err


def test_harness_errors_go_through_the_same_printer(capsys):
    """`wrt-harness` reuses `run_verb`: its errors are escaped too."""

    def verb(args):
        raise WrtError(f"{HOSTILE}: bad\nsecond line")

    assert run_verb(verb, argparse.Namespace(verb="render"), prog="wrt") == 2
    err = one_line_error(capsys, 2)
    assert r"evil\x1b[31m\x07\x7f\x9b: bad\x0asecond line" in err, err


# --- 4. a camera that float32 cannot resolve ---------------------------------------------------------


def camera(origin, look_at, up=None):
    text = GOOD.replace("origin = [0, 0, 5]", f"origin = {origin}").replace(
        "look_at = [0, 0, 0]", f"look_at = {look_at}"
    )
    return text.replace("[[material]]", f"up = {up}\n\n[[material]]") if up is not None else text


DEGENERATE_CAMERAS = [
    ("denormal view direction", camera("[0, 0, 0]", "[0, 0, 1e-40]"), "camera.look_at = [0.0, 0.0, 1e-40]"),
    ("view direction squared underflows", camera("[0, 0, 0]", "[1e-25, 0, 1e-25]"), "camera.look_at = [1e-25"),
    ("denormal origin", camera("[0, 0, 1e-40]", "[0, 0, 0]"), "camera.look_at = [0.0, 0.0, 0.0]"),
    ("equal in float32", camera("[1, 0, 0]", "[1.000000001, 0, 0]"), "camera.look_at = [1.000000001, 0.0, 0.0]"),
    ("tiny up", camera("[0, 0, 5]", "[0, 0, 0]", "[0, 1e-25, 0]"), "camera.up = [0, 1e-25, 0]"),
    ("denormal up", camera("[0, 0, 5]", "[0, 0, 0]", "[1e-40, 0, 0]"), "camera.up = [1e-40, 0, 0]"),
    ("up almost on the axis", camera("[0, 0, 5]", "[0, 0, 0]", "[1e-8, 0, 1]"), "camera.up = [1e-08, 0.0, 1.0]"),
    # |up|^2 is a normal float32 and up is 6 degrees off the axis, but cross(forward, up) underflows
    ("right underflows", camera("[0, 0, 5]", "[0, 0, 0]", "[2e-20, 0, 2e-19]"), "camera.up = [2e-20, 0.0, 2e-19]"),
]


@pytest.mark.parametrize("text, where", [c[1:] for c in DEGENERATE_CAMERAS], ids=[c[0] for c in DEGENERATE_CAMERAS])
def test_a_camera_float32_cannot_resolve_is_refused(tmp_path, capsys, text, where):
    err = render_bad(tmp_path, capsys, text, where)
    assert "float32" in err or "parallel" in err or "must differ" in err, err


def test_small_but_resolvable_cameras_still_load():
    for origin, look_at, up in [
        ([0, 0, 0], [0, 0, 1e-10], [0, 1, 0]),
        ([0, 0, 5], [0, 0, 0], [0, 1e-12, 0]),
        ([1e6, 0, 0], [1e6 + 1, 0, 0], [0, 0, 1]),
    ]:
        scene = parse_scene({"camera": {"origin": origin, "look_at": look_at, "up": up}})
        forward, right, _ = scene.camera.basis()
        assert abs(forward @ forward - 1) < 1e-12 and abs(right @ right - 1) < 1e-12


# --- 5. integer options are range-checked where they are parsed --------------------------------------

SCENE_OPTIONS = [
    (["render", "SCENE", "-o", "OUT", "--seed", "-1"], "--seed", "render.seed = -1"),
    (["render", "SCENE", "-o", "OUT", "--seed", str(2**31)], "--seed", "render.seed = 2147483648"),
    (["render", "SCENE", "-o", "OUT", "--width", "0"], "--width", "render.width = 0"),
    (["render", "SCENE", "-o", "OUT", "--height", "16385"], "--height", "render.height = 16385"),
    (["render", "SCENE", "-o", "OUT", "--spp", str(10**30)], "--spp", f"render.spp = {10**30}"),
    (["render", "SCENE", "-o", "OUT", "--max-depth", "0"], "--max-depth", "render.max_depth = 0"),
    (["render", "SCENE", "-o", "OUT", "--threads", "0"], "--threads", "--threads 0"),
    (["render", "SCENE", "-o", "OUT", "--threads", str(10**9)], "--threads", f"--threads {10**9}"),
    (["render", "SCENE", "-o", "OUT", "--checkpoint-every", "-2"], "--checkpoint-every", "--checkpoint-every -2"),
    (["rays", "SCENE", "--pixel", "0", "0", "-o", "OUT", "--capacity", "0"], "--capacity", "--capacity 0"),
    (["rays", "SCENE", "--pixel", "0", "0", "-o", "OUT", "--capacity", "-5"], "--capacity", "--capacity -5"),
    (["rays", "SCENE", "--pixel", "0", "0", "-o", "OUT", "--capacity", str(10**12)], "--capacity", "--capacity 1000"),
    (["rays", "SCENE", "--pixel", "0", "0", "-o", "OUT", "--depth", "5000"], "--max-depth", "max_depth = 5000"),
    (["rays", "SCENE", "--grid", "0", "2", "-o", "OUT"], "--grid", "--grid 0"),
    (["rays", "SCENE", "--pixel", "0", "0", "-o", "OUT", "--samples", str(10**12)], "--samples", "--samples 1000"),
    (["stress", "--seed", "-1"], "--seed", "--seed -1"),
    (["stress", "--rays", str(10**15)], "--rays", f"--rays {10**15}"),
]


@pytest.mark.parametrize("argv, option, shown", SCENE_OPTIONS, ids=[" ".join(a) for a, _, _ in SCENE_OPTIONS])
def test_out_of_range_integer_options_are_one_line_before_any_work(tmp_path, capsys, monkeypatch, argv, option, shown):
    scene = tmp_path / "scene.toml"
    scene.write_text(GOOD)
    out = tmp_path / ("out.png" if argv[0] == "rays" else "out.exr")
    argv = [str(scene) if a == "SCENE" else str(out) if a == "OUT" else a for a in argv]
    monkeypatch.setattr(wrt.rayview, "run", lambda *a, **k: pytest.fail("traced before checking the options"))
    monkeypatch.setattr(wrt.stress, "command", lambda *a, **k: pytest.fail("stressed before checking the options"))
    monkeypatch.setattr(wrt.renderer, "render", lambda *a, **k: pytest.fail("rendered before checking the options"))
    err = one_line_error(capsys, main(argv))
    assert option in err and shown in err and "must be" in err, err
    assert "Traceback" not in err and not out.exists()


def test_every_integer_option_has_a_range():
    """No verb of the library takes a bare `type=int`: each integer option says its range."""
    parser, _ = _parser(plugins=False)
    verbs = next(a for a in parser._actions if a.dest == "verb").choices
    integer_options = []
    for name, sub in verbs.items():
        for action in sub._actions:
            assert action.type is not int, f"wrt {name} {action.option_strings}: type=int without a range"
            if getattr(action.type, "range", None) is not None:
                integer_options.append((name, action.dest))
    assert {("render", "seed"), ("rays", "capacity"), ("stress", "rays"), ("stress", "seed")} <= set(integer_options)


def test_non_integers_keep_argparse_s_exit_2():
    with pytest.raises(SystemExit) as e:
        main(["stress", "--seed", "1.5"])
    assert e.value.code == 2


# --- 6. numbers whose float32 products overflow ------------------------------------------------------

PATH = GOOD.replace("height = 16", 'height = 16\nintegrator = "path"')
OVERFLOWING = [
    (
        "velocity times shutter",
        GOOD.replace("look_at = [0, 0, 0]", "look_at = [0, 0, 0]\nshutter = [0, 1e10]").replace(
            'material = "red"', 'material = "red"\nvelocity = [1e10, 0, 0]'
        ),
        "shape[0].velocity = [10000000000.0, 0.0, 0.0]",
    ),
    (
        "negative shutter end",
        GOOD.replace("look_at = [0, 0, 0]", "look_at = [0, 0, 0]\nshutter = [-1e12, 0]").replace(
            'material = "red"', 'material = "red"\nvelocity = [0, 0, -1e9]'
        ),
        "shape[0].velocity = [0.0, 0.0, -1000000000.0]",
    ),
    (
        "area light radiance",
        PATH + '[[light]]\ntype = "area"\ncorner = [-1, 2, -1]\nedge_u = [2, 0, 0]\nedge_v = [0, 0, 2]\n'
        "radiance = [3.0e38, 3.0e38, 3.0e38]\n",
        "light[0].radiance = [3e+38, 3e+38, 3e+38]",
    ),
    (
        "point light intensity",
        GOOD + '[[light]]\ntype = "point"\nposition = [0, 3, 0]\nintensity = [1e20, 1, 1]\n',
        "light[0].intensity = [1e+20, 1, 1]",
    ),
    (
        "directional irradiance",
        GOOD + '[[light]]\ntype = "directional"\ndirection = [0, -1, 0]\nirradiance = [1, 2e19, 1]\n',
        "light[0].irradiance = [1, 2e+19, 1]",
    ),
    (
        "environment radiance",
        PATH + '[[light]]\ntype = "environment"\nradiance = [1e30, 1e30, 1e30]\n',
        "light[0].radiance = [1e+30, 1e+30, 1e+30]",
    ),
    (
        "material emission",
        GOOD.replace("albedo = [0.8, 0.1, 0.1]", "albedo = [0.8, 0.1, 0.1]\nemission = [5e25, 0, 0]"),
        "material[0].emission = [5e+25, 0, 0]",
    ),
    ("sphere centre", GOOD.replace("center = [0, 0, 0]", "center = [1e30, 0, 0]"), "shape[0].center = [1e+30, 0, 0]"),
    ("sphere radius", GOOD.replace("radius = 1.0", "radius = 1e19"), "shape[0].radius = 1e+19"),
]


@pytest.mark.parametrize("text, where", [o[1:] for o in OVERFLOWING], ids=[o[0] for o in OVERFLOWING])
def test_numbers_whose_products_overflow_float32_are_refused(tmp_path, capsys, text, where):
    render_bad(tmp_path, capsys, text, where, "1e+18")


def test_large_but_bounded_numbers_still_load():
    scene = parse_scene(
        {
            "camera": {"origin": [0, 0, 1e17], "look_at": [0, 0, 0], "shutter": [-1e9, 1e9]},
            "shape": [{"type": "sphere", "center": [0, 0, 0], "radius": 1e17, "velocity": [1e9, 0, 0]}],
            "light": [{"type": "point", "position": [0, 1e18, 0], "intensity": [1e18, 1e18, 1e18]}],
        }
    )
    assert scene.shapes[0].velocity == (1e9, 0.0, 0.0) and scene.lights[0].intensity == (1e18,) * 3


def test_the_bound_is_the_same_for_a_python_document():
    with pytest.raises(SceneError, match=r"api\.toml: light\[0\]\.radiance = \[3e\+38, 1, 1\]: .*1e\+18"):
        parse_scene(
            {
                "render": {"integrator": "path"},
                "camera": {"origin": [0, 0, 5], "look_at": [0, 0, 0]},
                "light": [{"type": "environment", "radiance": [3e38, 1, 1]}],
            },
            file="api.toml",
        )


@pytest.mark.parametrize(
    "argv",
    [
        ["render"],
        ["render", "s.toml", "-o", "o.png", "--sampler", "\x1b[31mbad\x07"],
        ["bogus\x1b"],
        ["stress", "--seed", "x"],
    ],
    ids=["missing arguments", "bad choice with control characters", "unknown verb", "not an integer"],
)
def test_argparse_errors_are_one_escaped_line(capsys, argv):
    """Errors argparse itself finds (a missing argument, a bad choice or type) follow the CLI's
    convention too: one line, control characters escaped, exit 2 (they printed the usage and
    the raw text)."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.count("\n") == 1 and ": error: " in err and "\x1b" not in err and "\x07" not in err
