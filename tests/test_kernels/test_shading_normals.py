"""Shading normals of smooth-shaded meshes (``shading_normal`` in kernels/traverse.py, ``surface_hit``
in kernels/hit.py): the normal of a hit is the barycentric interpolation of its triangle's vertex
normals (float64 reference, through instances too), the BSDF works in its frame (closed forms), and
both agree with Mitsuba 3's ``si.sh_frame.n`` and images on the same files."""

import numpy as np
import pytest
import warp as wp
from conftest import EXAMPLES, make_scene
from wrt_harness.mitsuba_peer import mitsuba_available

import wrt
from wrt.geometry import build

AVAILABLE, REASON = mitsuba_available()
TILT = np.radians(60.0)  # the vertex normals of the quad below lean this far from +z toward +x


def write_ply(path, vertices, faces, normals):
    """An ASCII PLY triangle mesh with vertex normals."""
    header = (
        f"ply\nformat ascii 1.0\nelement vertex {len(vertices)}\n"
        + "".join(f"property float {name}\n" for name in ("x", "y", "z", "nx", "ny", "nz"))
        + f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rows = [" ".join(f"{x:.9g}" for x in (*v, *n)) for v, n in zip(vertices, normals)]
    path.write_text(header + "\n".join(rows) + "\n" + "".join(f"3 {a} {b} {c}\n" for a, b, c in faces))
    return path


def tilted_quad(tmp_path):
    """The square [-1, 1]^2 at z = 0 (winding normal +z) whose four vertex normals all lean by TILT."""
    corners = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
    normal = (np.sin(TILT), 0.0, np.cos(TILT))
    return write_ply(tmp_path / "quad.ply", corners, [(0, 1, 2), (0, 2, 3)], [normal] * 4)


def toward(degrees):
    """The unit direction ``degrees`` from +z toward +x (negative: toward -x)."""
    a = np.radians(degrees)
    return np.array([np.sin(a), 0.0, np.cos(a)])


# (camera, light) directions from the quad, two-sided, and what the quad's diffuse albedo a shows
# under a directional light of irradiance E: a / pi E cos(angle from the shading normal to the light)
SIDES = {
    "lit above both": (0.0, 10.0, False, np.cos(TILT - np.radians(10.0))),
    # light 10 degrees below the geometric plane but 40 above the shading one: lit, as in Mitsuba 3
    "lit from below the geometric plane": (0.0, 100.0, False, np.cos(np.radians(100.0) - TILT)),
    # the camera 45 degrees toward -x sees the shading normal's back: one-sided black ...
    "one-sided back": (-45.0, -45.0, False, 0.0),
    # ... two-sided: the back lobe, about the reversed shading normal
    "two-sided back": (-45.0, -45.0, True, np.cos(np.pi - TILT - np.radians(45.0))),
}


@pytest.mark.parametrize("integrator", ["path", "whitted"])
@pytest.mark.parametrize("specialize", [False, True], ids=["all-features", "smooth variant"])
@pytest.mark.parametrize("case", list(SIDES))
def test_diffuse_quad_shades_with_the_interpolated_normal(device, tmp_path, integrator, specialize, case):
    """The BSDF's frame, cosines and sides are the shading normal's; flat shading keeps the face."""
    camera, light, two_sided, cosine = SIDES[case]
    albedo, irradiance = 0.5, 2.0
    view = toward(camera)
    images = {}
    for shading in ("smooth", "flat"):
        scene = make_scene(
            [{"type": "mesh", "file": str(tilted_quad(tmp_path)), "shading": shading, "material": "m"}],
            materials=[{"name": "m", "albedo": [albedo] * 3, "two_sided": two_sided}],
            lights=[{"type": "directional", "direction": list(-toward(light)), "irradiance": [irradiance] * 3}],
            camera={"type": "orthographic", "origin": list(5 * view), "look_at": [0, 0, 0], "width": 0.5},
            render={"width": 4, "height": 4, "integrator": integrator, "max_depth": 2},
        )
        images[shading] = wrt.render(scene, spp=1, specialize=specialize, device=device).rgb
    expected = albedo / np.pi * irradiance * max(cosine, 0.0)
    np.testing.assert_allclose(images["smooth"], expected, rtol=1e-5, atol=1e-7)
    flat = albedo / np.pi * irradiance * max(toward(light)[2], 0.0) if toward(camera)[2] > 0 else 0.0
    np.testing.assert_allclose(images["flat"], flat, rtol=1e-5, atol=1e-7)


@pytest.mark.skipif(not AVAILABLE, reason=REASON)
@pytest.mark.parametrize("case", list(SIDES))
def test_the_closed_forms_are_mitsubas(tmp_path, case):
    """Mitsuba 3 renders the same quad to the same values: the sides and the light from below the
    geometric plane are its conventions, not ours."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    camera, light, two_sided, cosine = SIDES[case]
    diffuse = {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.5}}
    look = mi.ScalarTransform4f().look_at(origin=list(5 * toward(camera)), target=[0, 0, 0], up=[0, 1, 0])
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 2},
            "sensor": {
                "type": "orthographic",
                "to_world": look @ mi.ScalarTransform4f().scale([0.25, 0.25, 1]),
                "film": {"type": "hdrfilm", "width": 4, "height": 4, "rfilter": {"type": "box"}},
                "sampler": {"type": "independent", "sample_count": 4},
            },
            "quad": {
                "type": "ply",
                "filename": str(tilted_quad(tmp_path)),
                "bsdf": {"type": "twosided", "inner": diffuse} if two_sided else diffuse,
            },
            "sun": {
                "type": "directional",
                "direction": list(-toward(light)),
                "irradiance": {"type": "rgb", "value": 2.0},
            },
        }
    )
    np.testing.assert_allclose(np.array(mi.render(scene)), 0.5 / np.pi * 2.0 * max(cosine, 0.0), rtol=1e-5, atol=1e-7)


# --- the normal of a hit against float64 -------------------------------------------------------


def bumpy_patch(rng):
    """A non-planar 4 x 4 grid of triangles over [-1, 1]^2 with random unit normals leaning up."""
    x, y = np.meshgrid(np.linspace(-1, 1, 5), np.linspace(-1, 1, 5))
    vertices = np.stack([x, y, 0.15 * np.sin(3 * x) * np.cos(2 * y)], axis=-1).reshape(-1, 3)
    normals = rng.normal(size=(25, 3)) * [0.4, 0.4, 1.0] + [0, 0, 1.5]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    i, j = np.meshgrid(np.arange(4), np.arange(4), indexing="ij")
    a = (i * 5 + j).ravel()
    faces = np.concatenate([np.stack([a, a + 1, a + 6], 1), np.stack([a, a + 6, a + 5], 1)])
    return vertices, faces, normals


def interpolated_normal(point, vertices, faces, normals):
    """float64 reference: the normalised barycentric interpolation of ``normals`` at ``point`` on
    the triangle of ``faces`` nearest to it (the one it lies in)."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    e1, e2, w = b - a, c - a, point - a
    m = np.cross(e1, e2)
    mm = np.einsum("ij,ij->i", m, m)
    b1 = np.einsum("ij,ij->i", np.cross(w, e2), m) / mm
    b2 = np.einsum("ij,ij->i", np.cross(e1, w), m) / mm
    b0 = 1 - b1 - b2
    outside = np.maximum(0, -np.stack([b0, b1, b2], 1)).sum(1) + np.abs(np.einsum("ij,ij->i", w, m)) / np.sqrt(mm)
    k = np.argmin(outside)
    n = b0[k] * normals[faces[k, 0]] + b1[k] * normals[faces[k, 1]] + b2[k] * normals[faces[k, 2]]
    return n / np.linalg.norm(n), m[k]


def test_normal_aov_is_the_interpolated_vertex_normal(device, tmp_path, rng):
    """Each pixel's normal AOV is the float64 barycentric interpolation of the hit triangle's
    vertex normals at its hit point, normalised, on the side the camera sees: on a mesh placed by
    a shear (normals by the inverse transpose) and moving (the AOVs show mid-shutter), and on an
    instance of it stretched non-uniformly and mirrored."""
    vertices, faces, normals = bumpy_patch(rng)
    ply = write_ply(tmp_path / "patch.ply", vertices, faces, normals)
    shear = [1.0, 0.3, 0.0, -1.2, 0.0, 0.8, 0.0, 0.0, 0.2, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    stretch = [-0.9, 0.0, 0.0, 1.2, 0.0, 0.5, 0.3, 0.0, 0.0, 0.0, 1.5, 0.2, 0.0, 0.0, 0.0, 1.0]  # mirrors too
    mesh = {"type": "mesh", "file": str(ply), "shading": "smooth"}
    scene = make_scene(
        [
            {**mesh, "transform": {"matrix": shear}, "velocity": [0.4, 0.2, 0.0]},
            {"type": "instance", "group": "patch", "transform": {"matrix": stretch}},
        ],
        groups=[{"name": "patch", "shape": [mesh]}],
        camera={"type": "orthographic", "origin": [0, 0, 5], "look_at": [0, 0, 0], "width": 4.0, "shutter": [0, 1]},
        render={"width": 40, "height": 30},
    )
    aovs = wrt.render(scene, spp=1, device=device).aovs
    ids, points, shown = aovs["object_id"].ravel(), aovs["position"].reshape(-1, 3), aovs["normal"].reshape(-1, 3)
    placed = scene.shapes[0]
    member, to_world = scene.groups[0].shapes[0], scene.shapes[1].matrix
    checked = 0
    for shape_id, p, n in zip(ids, points.astype(np.float64), shown.astype(np.float64)):
        if shape_id == 0:
            shift = 0.5 * np.array(placed.velocity)  # at mid-shutter
            expected, winding = interpolated_normal(p - shift, placed.vertices, placed.faces, placed.normals)
        elif shape_id == 1:
            q = np.linalg.solve(to_world[:3, :3], p - to_world[:3, 3])
            local, winding = interpolated_normal(q, member.vertices, member.faces, member.normals)
            inverse_transpose = np.linalg.inv(to_world[:3, :3]).T
            expected, winding = inverse_transpose @ local, inverse_transpose @ winding
            expected /= np.linalg.norm(expected)
        else:
            continue
        facing = -1.0 if winding[2] < 0 else 1.0  # the camera looks down -z: it sees the +z side
        np.testing.assert_allclose(n, facing * expected, atol=2e-5)
        checked += 1
    assert checked > 400 and {0, 1} <= set(ids)


# --- against Mitsuba 3 ---------------------------------------------------------------------------

MESHES = EXAMPLES / "meshes"
PLACEMENTS = """
    <shape type="obj">
        <string name="filename" value="{sphere}"/>
        <transform name="to_world"><matrix value="-0.7 0.3 0 -1.1  0 0.6 0.2 0.1  0.1 0 0.5 0  0 0 0 1"/></transform>
    </shape>
    <shape type="ply">
        <string name="filename" value="{torus}"/>
        <boolean name="flip_normals" value="true"/>
        <transform name="to_world"><scale x="0.6" y="0.4" z="0.5"/><rotate x="1" angle="30"/></transform>
    </shape>
    <shape type="shapegroup" id="group">
        <shape type="ply"><string name="filename" value="{torus}"/></shape>
    </shape>
    <shape type="instance">
        <ref id="group"/>
        <transform name="to_world">
            <scale x="0.3" y="0.5" z="0.4"/><rotate y="1" angle="40"/><translate x="1.1"/>
        </transform>
    </shape>
"""


@pytest.mark.skipif(not AVAILABLE, reason=REASON)
def test_hit_normals_are_mitsubas(device, tmp_path):
    """Through the Mitsuba importer: each pixel's normal AOV is Mitsuba's ``si.sh_frame.n`` of the
    same ray, turned to the geometric side the camera sees, for computed normals under a mirroring
    shear, the file's normals under flip_normals and a rotation, and an instance's."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    xml = tmp_path / "scene.xml"
    shapes = PLACEMENTS.format(sphere=MESHES / "coarse_sphere.obj", torus=MESHES / "coarse_torus.ply")
    sensor = """
    <sensor type="orthographic">
        <transform name="to_world">
            <scale x="1.8" y="1.8"/><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <film type="hdrfilm"><integer name="width" value="48"/><integer name="height" value="32"/></film>
    </sensor>"""
    xml.write_text(f'<scene version="3.0.0">{sensor}{shapes}</scene>')
    scene = wrt.load_scene(xml)
    assert [getattr(s, "normals", None) is not None for s in scene.shapes] == [True, True, False]
    aovs = wrt.render(scene, spp=1, device=device).aovs
    theirs = mi.load_file(str(xml))
    d = mi.Vector3f(0, 0, -1)
    checked = 0
    for p, n in zip(aovs["position"].reshape(-1, 3), aovs["normal"].reshape(-1, 3)):
        if not n.any():
            continue
        si = theirs.ray_intersect(mi.Ray3f(mi.Point3f(p[0], p[1], 5.0), d))
        assert si.is_valid() and abs(si.p[2] - p[2]) < 1e-4
        facing = -1.0 if si.n[2] < 0 else 1.0
        np.testing.assert_allclose(n, facing * np.array(si.sh_frame.n), atol=1e-4)
        checked += 1
    assert checked > 300


# --- the corner normals on their way to the device ----------------------------------------------


@pytest.mark.parametrize("smooth_top", [True, False], ids=["smooth shapes and group", "smooth group only"])
def test_corner_normals_follow_their_triangles_into_leaf_order(tmp_path, smooth_top):
    """``tri_normals`` stays parallel to ``tri_verts`` through the BVH's reordering and the groups'
    appending: a smooth mesh's triangles carry its vertex normals (a zero one replaced by the face
    normal), every other triangle zeros."""
    normals = [(0, 0, 1), (0.6, 0, 0.8), (0, 0, 0), (0, 0.6, 0.8)]  # the third: none
    quad = write_ply(
        tmp_path / "quad.ply", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [(0, 1, 2), (0, 2, 3)], normals
    )
    shading = "smooth" if smooth_top else "flat"
    scene = make_scene(
        [
            {"type": "triangle", "vertices": [[0, 0, 2], [1, 0, 2], [0, 1, 2]]},
            {"type": "mesh", "file": str(quad), "shading": shading, "transform": {"translate": [3, 0, 0]}},
            {"type": "mesh", "file": str(EXAMPLES / "meshes" / "cube.stl")},
            {"type": "instance", "group": "g", "transform": {"translate": [0, 4, 0]}},
        ],
        groups=[
            {
                "name": "g",
                "shape": [{"type": "mesh", "file": str(EXAMPLES / "meshes" / "tetra.obj"), "shading": "smooth"}],
            }
        ],
    )
    p = build(scene, wp.get_device("cpu"))
    assert p.tri_normals.shape == p.tri_verts.shape and p.tri_normals.dtype == np.float32
    smooth = {1: scene.shapes[1], 4: scene.groups[0].shapes[0]} if smooth_top else {4: scene.groups[0].shapes[0]}
    expected = {}
    for shape, mesh in smooth.items():
        corners = mesh.vertices.astype(np.float32)[mesh.faces]
        face = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]).astype(np.float64)
        face /= np.linalg.norm(face, axis=1, keepdims=True)
        vertex = mesh.normals[mesh.faces]
        vertex = np.where(np.any(vertex != 0, axis=2, keepdims=True), vertex, face[:, None])
        expected.update({(shape, c.tobytes()): n for c, n in zip(corners, vertex.astype(np.float32))})
    for shape, corners, got in zip(p.tri_shape, p.tri_verts, p.tri_normals):
        np.testing.assert_array_equal(got, expected.get((shape, corners.tobytes()), np.zeros((3, 3), np.float32)))
    assert sum(np.any(n != 0) for n in p.tri_normals) == 4 + (2 if smooth_top else 0)
