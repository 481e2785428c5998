"""Instancing: ``[[group]]`` shapes placed by ``instance`` shapes, traced through a two-level BVH.

The reference is the same scene with every instance written out as world-space geometry (the
instance's transform applied to the group's shapes in float64), traced through the ordinary
one-level BVH: the two must see the same surfaces at the same distances, with the same normals.
"""

import dataclasses

import numpy as np
import pytest
from conftest import CAMERA, Tracer

import wrt
from wrt.errors import SceneError
from wrt.geometry import build
from wrt.loader import parse_scene
from wrt.meshio import transform_matrix
from wrt.renderer import scene_features
from wrt.scene import Cylinder, Disk, Instance, Mesh, Polygon, Sphere

SHEAR = [[1.0, 0.4, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.3, 0.0, 0.7, 0.0], [0.0, 0.0, 0.0, 1.0]]


def grid_mesh(path, n):
    """An ASCII PLY of a bumpy height field with ``2 n^2`` triangles over [-1, 1]^2."""
    u = np.linspace(-1.0, 1.0, n + 1)
    x, y = np.meshgrid(u, u)
    z = 0.2 * np.sin(3 * x) * np.cos(2 * y)
    vertices = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    k = np.arange(n * (n + 1)).reshape(n, n + 1)[:, :n].ravel()
    faces = np.concatenate([np.stack([k, k + 1, k + n + 2], 1), np.stack([k, k + n + 2, k + n + 1], 1)])
    header = (
        f"ply\nformat ascii 1.0\nelement vertex {len(vertices)}\nproperty float x\nproperty float y\n"
        f"property float z\nelement face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    body = "\n".join(" ".join(f"{c:.7g}" for c in v) for v in vertices) + "\n"
    body += "\n".join("3 " + " ".join(map(str, f)) for f in faces) + "\n"
    path.write_text(header + body)
    return path


def scene_doc(mesh_file, instances, render=None):
    """Two groups: ``solid`` (a mesh, a polygon, a disk and a tube, any affine placement) and ``ball`` (a sphere,
    similarity placements only, so that the flattened reference is a sphere too)."""
    return {
        "render": render or {"width": 48, "height": 32, "integrator": "raycast"},
        "camera": {"origin": [0.0, 1.0, 9.0], "look_at": [0.0, 0.0, 0.0]},
        "material": [{"name": "red", "albedo": [0.8, 0.1, 0.1]}],
        "group": [
            {
                "name": "solid",
                "shape": [
                    {"type": "mesh", "file": str(mesh_file), "material": "red"},
                    {"type": "polygon", "vertices": [[-1, -1, 0.5], [1, -1, 0.5], [0, 1, 0.8]]},
                    {"type": "disk", "center": [0, 0, -0.6], "normal": [0, 0.3, 1], "radius": 0.6},
                    {"type": "cylinder", "p0": [-0.8, -0.8, 0], "p1": [-0.8, 0.8, 0.2], "radius": 0.25},
                ],
            },
            {"name": "ball", "shape": [{"type": "sphere", "center": [0.5, 0.0, 0.0], "radius": 0.7}]},
        ],
        "shape": [{"type": "plane", "point": [0, -3, 0], "normal": [0, 1, 0]}, *instances],
    }


INSTANCES = [
    {"type": "instance", "group": "solid"},
    {"type": "instance", "group": "solid", "transform": {"translate": [2.5, 0, 0], "rotate": [30, 60, 0]}},
    {"type": "instance", "group": "solid", "transform": {"translate": [-2.5, 1, -1], "matrix": SHEAR}},
    {"type": "instance", "group": "solid", "transform": {"translate": [0, -2, 0], "scale": [1.5, -0.5, 1]}},
    {"type": "instance", "group": "ball", "transform": {"translate": [0, 2, 0], "rotate": [0, 0, 45], "scale": 1.3}},
]


def flattened(scene):
    """``scene`` with each instance replaced by its group's shapes in world space (float64)."""
    shapes = []
    for shape in scene.shapes:
        if not isinstance(shape, Instance):
            shapes.append(shape)
            continue
        m = shape.matrix
        for member in scene.groups[shape.group].shapes:
            if isinstance(member, Sphere):  # similarity transforms only (see scene_doc)
                center = tuple(m[:3, :3] @ member.center + m[:3, 3])
                shapes.append(
                    dataclasses.replace(member, center=center, radius=member.radius * np.linalg.norm(m[:3, 0]))
                )
            elif isinstance(member, (Disk, Cylinder)):
                shapes.append(dataclasses.replace(member, to_world=m @ member.to_world))
            elif isinstance(member, Mesh):
                shapes.append(dataclasses.replace(member, vertices=member.vertices @ m[:3, :3].T + m[:3, 3]))
            else:
                assert isinstance(member, Polygon)
                vertices = np.asarray(member.vertices) @ m[:3, :3].T + m[:3, 3]
                normal = np.linalg.inv(m[:3, :3]).T @ member.normal  # the side stays the front
                shapes.append(
                    dataclasses.replace(
                        member, vertices=tuple(map(tuple, vertices)), normal=tuple(normal / np.linalg.norm(normal))
                    )
                )
    return dataclasses.replace(scene, shapes=tuple(shapes), groups=())


def object_ids(scene, shape_ids):
    """The flattened scene's shape ids mapped back to the instanced scene's (one per instance)."""
    owner = []
    for i, shape in enumerate(scene.shapes):
        owner += [i] * (len(scene.groups[shape.group].shapes) if isinstance(shape, Instance) else 1)
    return np.where(shape_ids >= 0, np.asarray(owner)[np.maximum(shape_ids, 0)], -1)


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    mesh = grid_mesh(tmp_path_factory.mktemp("instances") / "grid.ply", 24)
    scene = parse_scene(scene_doc(mesh, INSTANCES), file="<test>")
    return scene, flattened(scene)


def test_instances_trace_like_the_flattened_scene(scenes, rng, device):
    scene, flat = scenes
    origins = rng.uniform(-6.0, 6.0, size=(20000, 3))
    directions = rng.normal(size=(20000, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    t, shape = Tracer(scene).closest(origins, directions)
    t_flat, shape_flat = Tracer(flat).closest(origins, directions)
    t_brute, shape_brute = Tracer(scene).closest(origins, directions, brute_force=True)
    np.testing.assert_array_equal(t, t_brute)  # the two-level tree against every primitive
    np.testing.assert_array_equal(shape, shape_brute)
    same = shape == object_ids(scene, shape_flat)
    assert np.count_nonzero(~same) <= 5, "instanced and flattened geometry disagree beyond silhouette rounding"
    hit = same & (shape >= 0)
    assert hit.sum() > 5000 and len(set(shape[hit])) == len(scene.shapes)
    np.testing.assert_allclose(t[hit], t_flat[hit], rtol=2e-5, atol=2e-5)
    occluded = Tracer(scene).occluded(origins, directions)
    np.testing.assert_array_equal(occluded, shape >= 0)


def test_instanced_images_and_aovs_match_the_flattened_scene(scenes, device):
    scene, flat = scenes
    a, b = wrt.render(scene, device=device), wrt.render(flat, device=device)
    ids_b = object_ids(scene, b.aovs["object_id"])
    same = a.aovs["object_id"] == ids_b
    assert np.count_nonzero(~same) <= 3
    np.testing.assert_allclose(a.aovs["depth"][same], b.aovs["depth"][same], rtol=1e-4)
    normals = np.einsum("ijk,ijk->ij", a.aovs["normal"], b.aovs["normal"])[same & (ids_b >= 0)]
    assert normals.min() > 1 - 1e-4  # the inverse transpose of the transform, sides kept
    np.testing.assert_allclose(a.rgb[same], b.rgb[same], atol=1e-4)


def test_moving_instances_blur_like_moving_shapes(scenes, device):
    scene, _ = scenes
    shapes = list(scene.shapes)
    shapes[1] = dataclasses.replace(shapes[1], velocity=(2.0, 0.0, 0.0))
    render = dataclasses.replace(scene.render, spp=16, integrator="path", max_depth=2)
    camera = dataclasses.replace(scene.camera, shutter=(0.0, 1.0))
    moving = dataclasses.replace(scene, shapes=tuple(shapes), render=render, camera=camera)
    flat = flattened(moving)
    flat = dataclasses.replace(
        flat,
        shapes=tuple(
            dataclasses.replace(s, velocity=(2.0, 0.0, 0.0)) if k in (1, 2) else s for k, s in enumerate(flat.shapes)
        ),
    )
    a, b = wrt.render(moving, device=device), wrt.render(flat, device=device)
    assert scene_features(moving).motion and scene_features(moving).instances
    assert np.mean(np.abs(a.rgb - b.rgb)) < 2e-3 * max(np.mean(b.rgb), 1e-3)


def test_a_thousand_instances_of_a_large_mesh_share_one_copy(tmp_path, device):
    """1,000 instances of a 100k-triangle mesh: the primitives of one mesh plus 1,000 transforms."""
    mesh = grid_mesh(tmp_path / "big.ply", 224)  # 100,352 triangles
    instances = [
        {"type": "instance", "group": "solid", "transform": {"translate": [3 * (k % 40) - 60, 3 * (k // 40) - 36, -40]}}
        for k in range(1000)
    ]
    doc = scene_doc(mesh, instances, render={"width": 128, "height": 96, "integrator": "raycast"})
    doc["camera"] = {"origin": [0.0, 0.0, 25.0], "look_at": [0.0, 0.0, 0.0], "fov": 90}
    scene = parse_scene(doc, file="<test>")
    prims = build(scene, "cpu")
    assert len(prims.tri_shape) == 100_352 and len(prims.inst_shape) == 1000
    nodes = prims.bvh.nodes.shape[0]
    assert nodes < 100_352  # one tree over the mesh, one over the instances: not 1,000 copies
    ids = wrt.render(scene, device=device).aovs["object_id"]
    assert len(np.unique(ids[ids >= 1])) > 500  # most instances are seen


def test_scenes_without_instances_compile_no_instance_code(scenes):
    scene, flat = scenes
    assert scene_features(scene).instances and not scene_features(flat).instances


@pytest.mark.parametrize(
    "change, match",
    [
        (
            lambda d: d["shape"].append({"type": "instance", "group": "nope"}),
            r"shape\[6\]\.group = 'nope': no \[\[group\]\]",
        ),
        (
            lambda d: d["shape"].append({"type": "instance", "group": "ball", "material": "red"}),
            r"material.*is not for an instance",
        ),
        (
            lambda d: d["group"].append(
                {"name": "ball", "shape": [{"type": "sphere", "center": [0, 0, 0], "radius": 1}]}
            ),
            r"group\[2\]\.name = 'ball': is already used",
        ),
        (lambda d: d["group"].append({"name": "empty", "shape": []}), r"group\[2\]\.shape .*non-empty array of tables"),
        (
            lambda d: d["group"][1]["shape"].append({"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0]}),
            r"group\[1\]\.shape\[1\]\.type = 'plane'",
        ),
        (
            lambda d: d["group"][1]["shape"].append({"type": "instance", "group": "solid"}),
            r"group\[1\]\.shape\[1\]\.type = 'instance'",
        ),
        (
            lambda d: d["shape"].append({"type": "instance", "group": "ball", "transform": {"scale": [1, 0, 1]}}),
            r"transform\.scale",
        ),
    ],
)
def test_bad_groups_and_instances_are_refused(tmp_path, change, match):
    doc = scene_doc(grid_mesh(tmp_path / "g.ply", 2), INSTANCES)
    change(doc)
    with pytest.raises(SceneError, match=match):
        parse_scene(doc, file="<test>")


def test_instance_transform_composes_like_a_mesh_transform():
    m = transform_matrix(translate=(1, 2, 3), rotate=(10, 20, 30), scale=(1, 2, 3), matrix=SHEAR)
    doc = {
        "camera": CAMERA,
        "group": [{"name": "g", "shape": [{"type": "sphere", "center": [0, 0, 0], "radius": 1}]}],
        "shape": [
            {
                "type": "instance",
                "group": "g",
                "transform": {"translate": [1, 2, 3], "rotate": [10, 20, 30], "scale": [1, 2, 3], "matrix": SHEAR},
            }
        ],
    }
    np.testing.assert_array_equal(parse_scene(doc).shapes[0].matrix, m)


def test_ray_viewer_draws_instances_under_the_recorded_hits(scenes):
    """``wrt rays``: an instance is drawn as its group's shapes through its transform, and the hit
    points recorded on it lie on the drawn surface; the segments name the instance's shape."""
    import pyvista as pv

    from wrt import rayview
    from wrt.rays import trace_rays

    scene, _ = scenes
    tree = trace_rays(scene, [(x, y) for x in range(0, 48, 3) for y in range(0, 32, 3)])
    blocks = rayview.ray_blocks(tree)
    assert [k for k in blocks["geometry"].keys() if "instance" in k] == [f"shape[{i}] instance" for i in range(1, 6)]
    on_instances = tree.hit & (tree.shape >= 1)
    assert on_instances.sum() > 20
    for i in np.unique(tree.shape[on_instances]):
        drawn = blocks["geometry"][f"shape[{i}] instance"]
        hits = tree.end[on_instances & (tree.shape == i)]
        _, closest = pv.PolyData(drawn).find_closest_cell(hits, return_closest_point=True)
        assert np.linalg.norm(closest - hits, axis=1).max() < 2e-2  # spheres drawn as 96 x 64 facets
