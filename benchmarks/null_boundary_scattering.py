"""Single scattering toward a mesh emitter, in a fog bounded by a null sphere and in an unbounded
one: wrt and Mitsuba 3 against an independent float64 estimate (numpy), the measurement behind
test_homo_area_light's entry in docs/mitsuba.md.

    python -m wrt_benchmarks.null_boundary_scattering [-o FILE.json]

Each case is a Mitsuba XML scene (written to a temporary folder), rendered at max_depth 2 (the
camera segment, then one scattering: single scattering only) by wrt and by Mitsuba's ``volpath``
(two seeds each), and estimated by ``single_scattering``: a uniform point on the image (each
pixel's box), the camera ray's scattering distance from its (truncated) exponential, a uniform
point on the emitter's area, the closed-form transmittance to it, the isotropic phase function.
The means compared are over the fog's pixels (wrt's ``object_id``: the first hit is the fog's
boundary; all pixels where there is none). Cases: the fog of test_homo_area_light (its polygonal
sphere, radius 0.5; the estimate takes the analytic sphere, a little larger) seen through its
perspective camera, at two extinctions, with its emitting cube flat-shaded; an analytic sphere
seen by an orthographic camera from outside and from inside (its rays start in the fog: only the
light's paths cross the boundary); and the cube in an unbounded fog (no boundary).
"""

from __future__ import annotations

import argparse
import math
import tempfile
from importlib import resources
from pathlib import Path

import numpy as np

MESHES = Path(str(resources.files("wrt.examples"))) / "mitsuba" / "participating_media" / "meshes"
EMISSION = 10.0  # W/(m^2 sr), grey
CUBE_OFFSET = (0.8, 0.0, 0.0)  # test_homo_area_light's translation of its emitting cube
X_FOV = 34.022057  # degrees: Mitsuba's default perspective field of view (its 50 mm lens), along x


def cube_triangles(offset=CUBE_OFFSET) -> np.ndarray:
    """(12, 3, 3): the triangles of ``angled_cube.obj`` moved by ``offset``, wound outward."""
    vertices, faces = [], []
    with open(MESHES / "angled_cube.obj") as f:
        for line in f:
            p = line.split()
            if p and p[0] == "v":
                vertices.append([float(x) for x in p[1:4]])
            elif p and p[0] == "f":
                faces.append([int(x.split("/")[0]) - 1 for x in p[1:]])
    return (np.array(vertices) + offset)[np.array(faces)]


def single_scattering(rays, sigma_t, albedo, triangles, emission, samples, rng, radius=None) -> float:
    """The mean single-scattered radiance of ``samples`` camera rays (``rays(n, rng)``: origins and
    unit directions, (n, 3) each) in a homogeneous isotropic medium filling the sphere of
    ``radius`` at the origin (None: all space), lit by ``triangles`` emitting ``emission`` on
    their outward sides; a ray missing the sphere counts 0."""
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    areas = 0.5 * np.linalg.norm(cross, axis=1)
    normals = cross / (2.0 * areas[:, None])
    cdf = np.cumsum(areas) / areas.sum()
    total, batch = 0.0, 500_000
    for _ in range(samples // batch):
        o, d = rays(batch, rng)
        u = rng.random(batch)
        if radius is None:
            hit, weight = np.ones(batch, bool), np.full(batch, albedo)
            point = o + d * (-np.log(1.0 - u) / sigma_t)[:, None]
        else:
            b = np.sum(o * d, axis=1)
            disc = b * b - np.sum(o * o, axis=1) + radius * radius
            hit = disc > 0.0
            root = np.sqrt(np.maximum(disc, 0.0))
            t0 = np.maximum(-b - root, 0.0)  # 0 for a ray starting inside
            length = np.maximum(-b + root - t0, 0.0)
            scattered = 1.0 - np.exp(-sigma_t * length)
            weight = scattered * albedo
            point = o + d * (t0 - np.log(1.0 - u * scattered) / sigma_t)[:, None]
        tri = np.minimum(np.searchsorted(cdf, rng.random(batch)), len(areas) - 1)
        r1, r2 = np.sqrt(rng.random(batch)), rng.random(batch)
        c = triangles[tri]
        on_light = c[:, 0] * (1 - r1)[:, None] + c[:, 1] * (r1 * (1 - r2))[:, None] + c[:, 2] * (r1 * r2)[:, None]
        to = on_light - point
        dist = np.linalg.norm(to, axis=1)
        wi = to / dist[:, None]
        cos_light = -np.sum(normals[tri] * wi, axis=1)
        if radius is None:
            inside = dist
        else:
            b = np.sum(point * wi, axis=1)
            inside = -b + np.sqrt(np.maximum(b * b - np.sum(point * point, axis=1) + radius * radius, 0.0))
        radiance = emission / (4.0 * math.pi) * np.exp(-sigma_t * inside) * cos_light / dist**2 * areas.sum()
        total += np.sum(np.where(hit & (cos_light > 0.0), weight * radiance, 0.0))
    return total / (samples // batch * batch)


def orthographic_rays(origin_z: float, half_width: float):
    """Rays along -z from uniform points of the square of ``half_width`` at z = ``origin_z``."""

    def rays(n, rng):
        o = np.column_stack([rng.uniform(-half_width, half_width, (n, 2)), np.full(n, origin_z)])
        return o, np.tile([0.0, 0.0, -1.0], (n, 1))

    return rays


def perspective_rays(pixels: np.ndarray, size: int):
    """Rays of test_homo_area_light's camera (origin (0, 0.5, 4) toward (0, -0.5, 0), ``X_FOV``)
    through uniform points of the ``pixels`` (rows, columns) of a ``size`` x ``size`` image."""
    origin = np.array([0.0, 0.5, 4.0])
    forward = np.array([0.0, -1.0, -4.0]) / math.sqrt(17.0)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    tan_half = math.tan(math.radians(X_FOV) / 2.0)

    def rays(n, rng):
        k = rng.integers(0, len(pixels), n)
        x = (pixels[k, 1] + rng.random(n)) / size
        y = (pixels[k, 0] + rng.random(n)) / size
        d = forward + np.outer((2 * x - 1) * tan_half, right) + np.outer((1 - 2 * y) * tan_half, up)
        return np.tile(origin, (n, 1)), d / np.linalg.norm(d, axis=1)[:, None]

    return rays


SENSORS = {
    "perspective": """<sensor type="perspective"><float name="near_clip" value="1"/>
        <transform name="to_world"><lookat origin="0, 0.5, 4" target="0, -0.5, 0" up="0, 1, 0"/></transform>
        {medium}<film type="hdrfilm"><integer name="width" value="48"/><integer name="height" value="48"/>
        <rfilter type="box"/></film><sampler type="independent"><integer name="sample_count" value="{spp}"/>
        </sampler></sensor>""",
    "orthographic": """<sensor type="orthographic"><float name="near_clip" value="0.0001"/>
        <transform name="to_world"><scale x="{half}" y="{half}"/>
        <lookat origin="0, 0, {z}" target="0, 0, 0" up="0, 1, 0"/></transform>
        {medium}<film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/>
        <rfilter type="box"/></film><sampler type="independent"><integer name="sample_count" value="{spp}"/>
        </sampler></sensor>""",
}
FOG = {
    "mesh sphere": '<shape type="obj"><string name="filename" value="{meshes}/sphere.obj"/><bsdf type="null"/>'
    '<ref id="fog" name="interior"/></shape>',
    "sphere": '<shape type="sphere"><float name="radius" value="0.5"/><bsdf type="null"/>'
    '<ref id="fog" name="interior"/></shape>',
    "unbounded": "",
}


def orthographic_frame(fog: str, inside: bool) -> tuple[float, float]:
    """The orthographic camera's ``(z, half_width)``: 5 and 0.2 outside the fog's sphere, 2 in the
    unbounded fog, 0.45 and 0.1 inside the sphere (every ray starts in it)."""
    if inside:
        return 0.45, 0.1
    return (2.0 if fog == "unbounded" else 5.0), 0.2


def scene_xml(sensor: str, fog: str, sigma_t: float, albedo: float, spp: int, inside: bool = False) -> str:
    """The Mitsuba XML of one case: ``sensor`` and ``fog`` keys of ``SENSORS`` and ``FOG``; the
    camera in the fog where ``inside`` (or the fog is unbounded)."""
    in_fog = inside or fog == "unbounded"
    unbounded = fog == "unbounded"
    camera_medium = '<ref id="fog" name="medium"/>' if in_fog else ""
    z, half = orthographic_frame(fog, inside)
    return f"""<scene version="3.0.0">
    <integrator type="volpath"><integer name="max_depth" value="2"/></integrator>
    <medium id="fog" type="homogeneous"><float name="sigma_t" value="{sigma_t}"/>
        <rgb name="albedo" value="{albedo}"/></medium>
    {SENSORS[sensor].format(spp=spp, z=z, half=half, medium=camera_medium)}
    {FOG[fog].format(meshes=MESHES)}
    <shape type="obj"><string name="filename" value="{MESHES}/angled_cube.obj"/>
        <boolean name="face_normals" value="true"/><transform name="to_world"><translate x="0.8"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
        <emitter type="area"><rgb name="radiance" value="{EMISSION}"/></emitter>
        {'<ref id="fog" name="exterior"/>' if unbounded else ""}</shape>
</scene>"""


CASES = (  # name, sensor, fog, sigma_t, albedo, camera inside the fog's sphere
    ("perspective, polygonal sphere, sigma_t 2.5", "perspective", "mesh sphere", 2.5, 0.9, False),
    ("perspective, polygonal sphere, sigma_t 0.5", "perspective", "mesh sphere", 0.5, 0.9, False),
    ("orthographic, analytic sphere, sigma_t 2.5", "orthographic", "sphere", 2.5, 0.9, False),
    ("orthographic, camera inside the analytic sphere, sigma_t 2.5", "orthographic", "sphere", 2.5, 0.9, True),
    ("orthographic, unbounded fog, sigma_t 0.5", "orthographic", "unbounded", 0.5, 0.9, False),
)


def measure(spp_wrt: int = 2048, spp_mitsuba: int = 4096, samples: int = 4_000_000) -> list[dict]:
    """Each case's fog mean by wrt, Mitsuba and the estimate, and the two ratios to the estimate."""
    import mitsuba as mi

    import wrt

    mi.set_variant("scalar_rgb")
    rng = np.random.default_rng(7)
    out = []
    with tempfile.TemporaryDirectory() as folder:
        for name, sensor, fog, sigma_t, albedo, inside in CASES:
            path = Path(folder) / "scene.xml"
            path.write_text(scene_xml(sensor, fog, sigma_t, albedo, spp_mitsuba, inside))
            scene = wrt.load_scene(str(path))
            renders = [wrt.render(scene, spp=spp_wrt, seed=seed) for seed in (1, 2)]
            everywhere = fog == "unbounded" or inside
            mask = np.ones(renders[0].rgb.shape[:2], bool) if everywhere else renders[0].aovs["object_id"] == 0
            ours = float(np.mean([r.rgb[..., 0][mask].mean() for r in renders]))
            theirs = float(
                np.mean([np.array(mi.render(mi.load_file(str(path)), seed=s))[..., 0][mask].mean() for s in (1, 2)])
            )
            if sensor == "perspective":
                rays = perspective_rays(np.argwhere(mask), mask.shape[0])
            else:
                rays = orthographic_rays(*orthographic_frame(fog, inside))
            radius = None if fog == "unbounded" else 0.5
            estimate = single_scattering(rays, sigma_t, albedo, cube_triangles(), EMISSION, samples, rng, radius)
            out.append(
                {
                    "case": name,
                    "estimate": estimate,
                    "wrt": ours,
                    "mitsuba": theirs,
                    "wrt_over_estimate": ours / estimate - 1.0,
                    "mitsuba_over_estimate": theirs / estimate - 1.0,
                }
            )
            print(f"{name}: wrt {ours / estimate - 1:+.4f}, Mitsuba {theirs / estimate - 1:+.4f}", flush=True)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m wrt_benchmarks.null_boundary_scattering")
    parser.add_argument("-o", "--output", help="write the results as JSON here")
    args = parser.parse_args(argv)
    results = measure()
    if args.output:
        from wrt.files import write_json

        write_json(args.output, {"cases": results, "spp": {"wrt": "2 x 2048", "mitsuba": "2 x 4096 (volpath)"}})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
