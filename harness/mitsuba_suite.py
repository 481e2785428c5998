"""Scenes judged by Mitsuba 3's render-test criterion against stored Mitsuba references, as
Mitsuba's own suite stores its references.

Suites (``SUITES``): ``suite`` (``examples/mitsuba/suite``: scenes written the way Mitsuba's
render tests write theirs, 32 x 32), ``participating_media`` (``examples/mitsuba/
participating_media``: the scenes of Mitsuba 3's participating-media render tests, 48 x 48, their
own resolution), ``bsdf_spheres`` (``examples/mitsuba/bsdf_spheres``: its textured principled BSDF
and normal-map tests, 48 x 48, their films fixed at that size), ``bsdf_spheres_lights`` (the same
folder's twelve spheres and two leaves of every material kind under an area light, a constant
sky, an environment map and a point light, 128 x 128, fixed), nine of one film size each over
``examples/mitsuba/render_tests`` (eleven more of Mitsuba's own render tests, named after their
mitsuba-data folders: ``floating_sphere``, ``spot_light``, ``projector``, ``orthographic_sensor``,
``instancing``, ``texture_interp``, ``mesh_tangents``, ``various_shapes``, ``vertex_tangents``)
and ``various_emitters`` (``examples/mitsuba/various_emitters``: its two scenes of every emitter
kind, 512 x 64, their own size: one rendered by wrt's path tracer, one by its light tracer).
Each scene is rendered by wrt at the suite's budget of 2e6 samples an image (``Suite.spp`` per pixel) and judged by
`wrt_harness.mitsuba_peer.mitsuba_z_test` against Mitsuba's render of the same file through a
``moment`` integrator at ``Suite.reference_spp`` (mean and per-sample variance in CIE XYZ), stored
in ``reference_images/mitsuba/SUITE/NAME.npz`` with the Mitsuba version, variant, seed and spp that
made it. References are made only on purpose (scalar_rgb on 2 cores: about a minute a scene)::

    python -m wrt_harness.mitsuba_suite regenerate SUITE [NAME ...]

``Suite.scenes`` lists the scenes wrt imports exactly and that pass; ``Suite.failing`` those it
imports but that fail the criterion, with what was measured (its reference is stored: regenerate
and test it by name).

The cross-checks of wrt's own Mitsuba examples (``CROSSCHECKS``: image means within 2% and SSIM,
Mitsuba at 8x wrt's spp) compare with Mitsuba's image of each scene, stored likewise in
``reference_images/mitsuba/crosscheck/NAME.npz`` (``python -m wrt_harness.mitsuba_suite images
[NAME ...]``): the tests need no Mitsuba, and spend no time on it.
"""

from __future__ import annotations

import argparse
import io
import sys
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from wrt.files import write_atomic

from .mitsuba_peer import render_mitsuba, render_mitsuba_moments, variant

EXAMPLES = Path(str(resources.files("wrt.examples"))) / "mitsuba"
REFERENCES = Path(str(resources.files("wrt_harness.reference_images"))) / "mitsuba"
SAMPLES = 2_000_000  # samples an image in Mitsuba's render tests
SEED = 7


@dataclass(frozen=True)
class Suite:
    """A folder of scenes whose films are ``width`` x ``height``, set by the XML parameters ``film``
    (``{"res": 32}``; none for scenes whose film is fixed). Mitsuba renders each reference with
    ``reference_params`` too (the light tracer's scenes: ``integrator = path``, which its
    ``moment`` integrator can wrap, as Mitsuba's suite makes their references); wrt renders scene
    ``name`` with the integrator ``integrators[name]`` where given, else the scene's own."""

    name: str
    width: int
    height: int
    scenes: tuple[str, ...]
    failing: dict[str, str] = field(default_factory=dict)
    film: dict[str, int] = field(default_factory=dict)
    reference_params: dict[str, str] = field(default_factory=dict)
    integrators: dict[str, str] = field(default_factory=dict)
    reference_factor: int = 4  # the references' samples per pixel over the test's
    folder: str = ""  # its scenes' folder of examples/mitsuba, when not its name

    @property
    def spp(self) -> int:
        return SAMPLES // (self.width * self.height)

    @property
    def reference_spp(self) -> int:
        return self.reference_factor * self.spp

    def scene_path(self, name: str) -> Path:
        return EXAMPLES / (self.folder or self.name) / f"{name}.xml"

    def reference_path(self, name: str) -> Path:
        return REFERENCES / self.name / f"{name}.npz"

    def reference(self, name: str) -> tuple[np.ndarray, np.ndarray, int]:
        """The stored ``(mean, variance, spp)`` of scene ``name`` (XYZ, float64)."""
        with np.load(self.reference_path(name)) as data:
            return data["mean"].astype(np.float64), data["variance"].astype(np.float64), int(data["spp"])

    def regenerate(self, name: str, spp: int | None = None) -> Path:
        """Render and store the reference of scene ``name`` (atomically)."""
        import mitsuba

        spp = spp or self.reference_spp
        params = {**self.film, **self.reference_params}
        mean, var = render_mitsuba_moments(self.scene_path(name), spp, seed=SEED, **params)
        buffer = io.BytesIO()
        np.savez_compressed(
            buffer,
            mean=mean.astype(np.float32),
            variance=var.astype(np.float32),
            spp=spp,
            seed=SEED,
            mitsuba=mitsuba.__version__,
            variant=variant(),
        )
        out = self.reference_path(name)
        write_atomic(out, buffer.getvalue())
        return out


SUITES = {
    suite.name: suite
    for suite in (
        Suite(
            "bsdf_spheres",
            48,
            48,
            (
                "test_texturedprincipled1",
                "test_texturedprincipled2",
                "test_texturedprincipledthin",
                "test_normalmap",
                "test_normalmap_roughconductor_path",
                "test_normalmap_identity_roughconductor_path",
            ),
        ),
        Suite(
            "bsdf_spheres_lights",
            128,
            128,
            ("test_arealight", "test_constant", "test_envmap", "test_pointlight"),
            folder="bsdf_spheres",
        ),
        Suite(
            "suite",
            32,
            32,
            (
                "envmap_path",
                "include_path_direct",
                "instances_path",
                "orthographic_direct",
                "spectra_path",
                "test_projector_constant_direct",
                "test_mesh_attributes_1_face_direct",
                "test_mesh_attributes_3_face_direct",
                "test_mesh_attributes_3_vertex_direct",
            ),
            film={"res": 32},
        ),
        Suite("floating_sphere", 48, 48, ("test_directional", "test_directional_direct"), folder="render_tests"),
        Suite("spot_light", 48, 48, ("test_spot", "test_spot_direct"), folder="render_tests"),
        Suite("projector", 48, 48, ("test_projector_textured_direct",), folder="render_tests"),
        Suite("orthographic_sensor", 200, 120, ("test_orthographic",), folder="render_tests"),
        Suite("instancing", 64, 64, ("test_instancing_path",), folder="render_tests"),
        Suite("texture_interp", 128, 128, ("test_texture_interp_direct",), folder="render_tests"),
        Suite("mesh_tangents", 256, 256, ("test_tangent_pole_path",), folder="render_tests"),
        Suite("various_shapes", 480, 480, ("test_various_shapes",), folder="render_tests/tests/scenes/various_shapes"),
        Suite(
            "vertex_tangents",
            64,
            48,
            ("test_anisotropic_tangents_path",),
            folder="render_tests/tests/scenes/vertex_tangents",
        ),
        Suite(
            "various_emitters",
            512,
            64,
            ("test_various_emitters", "test_various_emitters_ptracer"),
            film={"resx": 512, "resy": 64},
            reference_params={"integrator": "path"},
            integrators={"test_various_emitters": "path"},
            reference_factor=32,  # Mitsuba's path tracer sparkles on the back wall: at 4x its noise failed wrt
        ),
        Suite(
            "participating_media",
            48,
            48,
            (
                "test_hetero_sigmat",
                "test_hetero_sigmat_albedo",
                "test_hetero_spectral_sigmat",
                "test_hetero_spectral_sigmat_no_scattering_volpath",
                "test_homo_dielectric_envmap",
                "test_homo_emitter_inside_medium",
                "test_homo_null_envmap",
                "test_homo_obj_inside_medium",
                "test_homo_roughdielectric_spot_volpath",
                "test_homo_spectral_sigmat",
                "test_surf_area_light",
            ),
            {
                "test_homo_area_light": "6 of 12 seeds fail (99.61-99.74% of the pixel channels pass, 99.75%"
                " needed): pooled, the fog sphere's side facing the emitter is 4-10% bright (up to 9 standard"
                " errors), already in single scattering (max_depth 2: 4.6%, 1.8% with the emitter cube"
                " flat-shaded in both renderers), where an independent float64 estimate sides with wrt (within"
                " 0.1-0.7%) and puts Mitsuba 2.3-3.1% dark (docs/mitsuba.md); the broad 4% excess of the floor"
                " in the fog sphere's shadow was the smooth-shaded emitter cube's light-sampling cosine, now Mitsuba's"
                " (wrt.kernels.lights.emitting)",
            },
            film={"res": 48},
        ),
    )
}


@dataclass(frozen=True)
class Crosscheck:
    """A scene of ``examples/mitsuba`` (``folder`` below it) rendered at ``width`` x ``height``
    by wrt at ``spp`` and by Mitsuba at ``reference_spp`` (8x: its noise adds an eighth of wrt's
    to the comparison, which costs the tests half of what two renders at equal spp did for the
    same SSIM); ``res``: the XML sets its film by ``$res``, not ``$width`` and ``$height``."""

    name: str
    width: int
    height: int
    spp: int
    folder: str = ""
    res: bool = False

    @property
    def path(self) -> Path:
        return EXAMPLES / self.folder / f"{self.name}.xml"

    @property
    def reference_spp(self) -> int:
        return 8 * self.spp

    @property
    def image_path(self) -> Path:
        return REFERENCES / "crosscheck" / f"{self.name}.npz"

    def params(self) -> dict:
        return {"res": self.width} if self.res else {"width": self.width, "height": self.height}

    def image(self) -> np.ndarray:
        """Mitsuba's stored image (linear RGB, float64), checked to be of this size and ``reference_spp``."""
        with np.load(self.image_path) as data:
            image, spp = data["rgb"].astype(np.float64), int(data["spp"])
        if image.shape != (self.height, self.width, 3) or spp != self.reference_spp:
            raise ValueError(
                f"{self.image_path}: {image.shape} at {spp} spp, "
                f"not {self.width} x {self.height} at {self.reference_spp}"
            )
        return image

    def regenerate(self) -> Path:
        import mitsuba

        rgb = render_mitsuba(str(self.path), spp=self.reference_spp, seed=SEED, **self.params())
        buffer = io.BytesIO()
        np.savez_compressed(
            buffer, rgb=rgb, spp=self.reference_spp, seed=SEED, mitsuba=mitsuba.__version__, variant=variant()
        )
        write_atomic(self.image_path, buffer.getvalue())
        return self.image_path


CROSSCHECKS = {
    check.name: check
    for check in (
        Crosscheck("cornell_box", 32, 32, 2048, res=True),
        Crosscheck("glossy_sphere", 64, 48, 1024),
        Crosscheck("thin_lens", 64, 48, 512),
        Crosscheck("sheared_mesh", 64, 48, 512),
        Crosscheck("quadrics", 64, 48, 1024),
        Crosscheck("one_sided", 64, 48, 512),
        Crosscheck("instances", 64, 48, 512),
        Crosscheck("smooth_meshes", 64, 48, 512),
        Crosscheck("conductors", 64, 48, 512),
        Crosscheck("envmap", 64, 48, 512),
        Crosscheck("thin_dielectric", 64, 48, 512),
        Crosscheck("emissive_mesh", 64, 48, 512),
        Crosscheck("rough_dielectric", 64, 48, 512),
        Crosscheck("plastics", 64, 48, 512),
        Crosscheck("textures", 64, 48, 512),
        Crosscheck("textured_roughness", 64, 48, 512),
        Crosscheck("normal_map", 64, 48, 512),
        Crosscheck("mask", 64, 48, 512),
        Crosscheck("anisotropic", 64, 48, 512),
        Crosscheck("blend", 64, 48, 512),
        Crosscheck("projector", 64, 48, 512),
        Crosscheck("bumpmap", 64, 48, 512),
        Crosscheck("mesh_attributes", 64, 48, 512),
        Crosscheck("principled", 64, 48, 512),
        Crosscheck("textured_emission", 64, 48, 512),
        Crosscheck("fog_area_light", 48, 36, 512, folder="media"),
        Crosscheck("milk_in_glass", 48, 36, 512, folder="media"),
        Crosscheck("camera_in_fog", 48, 36, 512, folder="media"),
    )
}
"""Every cross-check by scene name (tests/test_wrt/test_mitsuba_crosscheck.py, test_media.py)."""


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m wrt_harness.mitsuba_suite")
    sub = parser.add_subparsers(dest="command", required=True)
    regen = sub.add_parser("regenerate", help="render and store Mitsuba's references")
    regen.add_argument("suite", choices=sorted(SUITES))
    regen.add_argument("names", nargs="*", help="scenes (default: every scene of the suite wrt imports)")
    regen.add_argument("--spp", type=int, default=None, help="reference samples per pixel (default: 4x the test's)")
    images = sub.add_parser("images", help="render and store Mitsuba's images of the cross-checks")
    images.add_argument("names", nargs="*", help="scenes (default: all)")
    args = parser.parse_args(argv)
    if args.command == "images":
        for name in args.names or CROSSCHECKS:
            if name not in CROSSCHECKS:
                print(f"no such cross-check: {name} (known: {', '.join(CROSSCHECKS)})", file=sys.stderr)
                return 2
            print(f"wrote {CROSSCHECKS[name].regenerate()}", flush=True)
        return 0
    suite = SUITES[args.suite]
    for name in args.names or (*suite.scenes, *suite.failing):
        if not suite.scene_path(name).is_file():
            print(f"no such scene: {suite.scene_path(name)}", file=sys.stderr)
            return 2
        print(f"wrote {suite.regenerate(name, args.spp)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
