"""Render orchestration (wrt/renderer.py), the raycast integrator and the `wrt render` command."""

import numpy as np
from conftest import make_scene

import wrt
import wrt.renderer
from wrt.cli import main
from wrt.imageio import read_image


def busy_scene(spp=1, width=96, height=64):
    shapes = [
        {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "grey"},
        {"type": "sphere", "center": [-0.8, 0, 0], "radius": 0.8, "material": "red"},
        {"type": "triangle", "vertices": [[0.2, -1, -1], [1.6, -1, -0.5], [0.9, 1.2, -0.8]]},
        {"type": "polygon", "vertices": [[-1, 0.8, -2], [1, 0.8, -2], [1, 2, -2], [0, 1.2, -2], [-1, 2, -2]]},
    ]
    materials = [{"name": "grey", "albedo": [0.5, 0.5, 0.5]}, {"name": "red", "albedo": [0.9, 0.2, 0.1]}]
    return make_scene(shapes, materials=materials, render={"width": width, "height": height, "spp": spp, "seed": 3})


def test_bit_identical_for_any_thread_count_and_tiling(monkeypatch):
    scene = busy_scene(spp=4)
    one = wrt.render(scene, threads=1)
    two = wrt.render(scene, threads=2)
    monkeypatch.setattr(wrt.renderer, "TILE_PIXELS", 333)  # tiles that cut rows anywhere
    odd = wrt.render(scene, threads=3)
    for other in (two, odd):
        assert np.array_equal(one.rgb, other.rgb)
        for name in one.aovs:
            assert np.array_equal(one.aovs[name], other.aovs[name])


def test_same_scene_seed_and_spp_give_the_same_image(device):
    scene = busy_scene(spp=4)
    a, b = wrt.render(scene, device=device), wrt.render(scene, device=device)
    assert np.array_equal(a.rgb, b.rgb)
    for name in a.aovs:
        assert np.array_equal(a.aovs[name], b.aovs[name])


def test_seed_changes_samples_but_not_aovs():
    scene = busy_scene(spp=4)
    a, b = wrt.render(scene, seed=1), wrt.render(scene, seed=2)
    assert not np.array_equal(a.rgb, b.rgb)
    assert np.abs(a.rgb - b.rgb).mean() < 0.02  # same image, different edge noise
    single = wrt.render(scene, spp=1)
    for name in a.aovs:  # AOVs come from the pixel-centre ray whatever the spp
        assert np.array_equal(a.aovs[name], single.aovs[name])


def test_flat_shading_is_albedo_times_cosine(device):
    """A plane facing the camera: radiance = albedo * |cos| of the angle between ray and normal."""
    scene = make_scene(
        [{"type": "plane", "point": [0, 0, -3], "normal": [0, 0, 1], "material": "m"}],
        materials=[{"name": "m", "albedo": [0.2, 0.4, 0.6]}],
        camera={"origin": [0, 0, 0], "look_at": [0, 0, -1], "fov": 60},
        render={"width": 40, "height": 30},
    )
    r = wrt.render(scene, device=device)
    d = r.aovs["position"] / r.aovs["depth"][..., None]
    cos = np.abs(d[..., 2])
    np.testing.assert_allclose(r.rgb, cos[..., None] * np.array([0.2, 0.4, 0.6]), rtol=1e-6)
    np.testing.assert_allclose(r.aovs["depth"], 3.0 / cos, rtol=1e-6)
    assert (r.aovs["normal"] == np.array([0, 0, 1], dtype=np.float32)).all()
    assert (r.aovs["object_id"] == 0).all()


def test_miss_aovs_and_normals_face_the_camera():
    r = wrt.render(busy_scene())
    miss = r.aovs["object_id"] == -1
    assert miss.any() and np.isinf(r.aovs["depth"][miss]).all() and (r.rgb[miss] == 0).all()
    hit = ~miss
    d = r.aovs["position"][hit] - np.array([0, 0, 5.0])
    assert (np.einsum("ij,ij->i", r.aovs["normal"][hit], d) < 0).all()
    np.testing.assert_allclose(np.linalg.norm(r.aovs["normal"][hit], axis=1), 1.0, rtol=1e-6)
    assert set(np.unique(r.aovs["object_id"])) == {-1, 0, 1, 2, 3}


def test_cli_writes_exr_with_all_aovs_for_a_mesh_scene(tmp_path):
    """The foundation's end-to-end case: spheres, a plane, a triangle, a non-convex polygon and the 100k+ PLY."""
    out = tmp_path / "showcase.exr"
    assert (
        main(
            [
                "render",
                "examples/showcase.toml",
                "-o",
                str(out),
                "--aov",
                "all",
                "--width",
                "160",
                "--height",
                "90",
                "--spp",
                "1",
            ]
        )
        == 0
    )
    image = read_image(out)
    assert image.rgb.shape == (90, 160, 3) and set(image.aovs) == {"depth", "normal", "object_id", "position"}
    n_shapes = len(wrt.load_scene("examples/showcase.toml").shapes)
    assert set(np.unique(image.aovs["object_id"])) == set(range(-1, n_shapes))  # every shape is visible
    assert image.metadata["spp"] == 1 and image.metadata["integrator"] == "raycast"
    assert [p.name for p in tmp_path.iterdir()] == ["showcase.exr"]


def test_cli_png_and_cuda_request_without_gpu(tmp_path, capsys):
    out = tmp_path / "a.png"
    assert main(["render", "examples/spheres.toml", "-o", str(out), "--width", "48", "--height", "32"]) == 0
    assert read_image(out).rgb.shape == (32, 48, 3)
    if not __import__("warp").is_cuda_available():
        assert main(["render", "examples/spheres.toml", "-o", str(tmp_path / "b.png"), "--device", "cuda"]) == 2
        assert "no CUDA device" in capsys.readouterr().err


def test_cli_max_depth_overrides_the_scene(tmp_path):
    """``--max-depth 1`` renders what the scene renders with ``max_depth = 1``: no mirror bounces."""
    scene = "examples/whitted/mirrors.toml"
    size = ["--width", "40", "--height", "30", "--spp", "1"]
    assert main(["render", scene, "-o", str(tmp_path / "one.exr"), "--max-depth", "1", *size]) == 0
    assert main(["render", scene, "-o", str(tmp_path / "full.exr"), *size]) == 0
    one, full = read_image(tmp_path / "one.exr").rgb, read_image(tmp_path / "full.exr").rgb
    small = wrt.loader.override_render(wrt.load_scene(scene), width=40, height=30, spp=1, max_depth=1)
    np.testing.assert_array_equal(one, wrt.render(small).rgb)
    assert not np.array_equal(one, full)


def test_nesting_deeper_than_the_media_stack_is_counted_not_silent():
    """Concentric ior-1.0 glass spheres (priority 0, so each nests in the last): 8 deep renders
    the background through them all; the 9th has no slot, and the samples that enter it are lost
    and counted instead of continuing in a wrong medium (issue 13: the 5th used to be dropped
    silently)."""
    for integrator in ("whitted", "path"):
        for depth, lost in ((8, False), (9, True)):
            shapes = [
                {"type": "sphere", "center": [0, 0, 0], "radius": 1.0 - 0.1 * k, "material": "glass"}
                for k in range(depth)
            ]
            render = {"width": 9, "height": 9, "spp": 1, "integrator": integrator, "max_depth": 64}
            lights = [{"type": "environment", "radiance": [1.0, 1.0, 1.0]}] if integrator == "path" else []
            if integrator == "whitted":
                render["background"] = [1.0, 1.0, 1.0]
            scene = make_scene(
                shapes,
                materials=[{"name": "glass", "type": "dielectric", "ior": 1.0}],
                lights=lights,
                camera={"origin": [0, 0, 3], "look_at": [0, 0, 0], "fov": 5.0},
                render=render,
            )
            result = wrt.render(scene)
            assert np.isfinite(result.rgb).all()
            assert (result.rejected_samples > 0) == lost, (integrator, depth, result.rejected_samples)
            if not lost:
                np.testing.assert_allclose(result.rgb, 1.0, rtol=1e-5)


def test_camera_media_are_the_dielectric_volumes_holding_the_camera():
    """A camera inside a glass cube mesh inside a water sphere starts in both, outermost first;
    a diffuse sphere, a glass sphere elsewhere and an open triangle do not count."""
    from wrt.bake import camera_media
    from wrt.stress.common import make_scene as scene_with_meshes
    from wrt.stress.common import split_cube

    v, f = split_cube()  # the closed cube [-1, 1]^3, its faces split (edges exactly on the ray's path)
    shapes = [
        {"type": "sphere", "center": [0, 0, 0], "radius": 3.0, "material": "water"},
        {"type": "sphere", "center": [0, 0, 0], "radius": 2.5, "material": "grey"},
        {"type": "sphere", "center": [9, 0, 0], "radius": 1.0, "material": "glass"},
        {"type": "triangle", "vertices": [[-5, -5, 0.5], [5, -5, 0.5], [0, 5, 0.5]], "material": "glass"},
    ]
    materials = [
        {"name": "water", "type": "dielectric", "ior": 1.33},
        {"name": "glass", "type": "dielectric", "ior": 1.5},
        {"name": "grey", "albedo": [0.5, 0.5, 0.5]},
    ]
    for origin, expected in (
        ([0.1, 0.2, 0.3], [0, 4]),
        ([0.0, 0.0, 0.0], [0, 4]),
        ([2.0, 0.0, 0.0], [0]),
        ([0, 4, 0], []),
    ):
        scene = scene_with_meshes(
            shapes, meshes=[(v, f, "glass")], materials=materials, camera={"origin": origin, "look_at": [0, 0, -10]}
        )
        assert camera_media(scene) == expected, origin
