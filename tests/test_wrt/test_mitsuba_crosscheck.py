"""The path integrator against Mitsuba 3 (an independent renderer) on the same scenes, imported
from Mitsuba XML (wrt/mitsuba/), Mitsuba's images stored (``wrt_harness.mitsuba_suite``)."""

import numpy as np
import pytest
from wrt_harness.mitsuba_suite import CROSSCHECKS
from wrt_harness.score import ssim

import wrt
from wrt.loader import override_render

CASES = [name for name, check in CROSSCHECKS.items() if not check.folder]
# What each adds, and what its test caught (SSIM and means measured against Mitsuba):
# cornell_box, glossy_sphere, thin_lens: the base cases; sheared_mesh: a mesh placed by a general
# affine to_world (issue 16); quadrics: disks (one elliptical, one emitting with flip_normals) and
# a cylinder; one_sided: one-sided BSDFs black from the back (all two-sided: red mean +23%, SSIM
# 0.81); instances: a shapegroup placed by three instances, one non-uniformly scaled;
# smooth_meshes: interpolated vertex normals (flat: SSIM 0.954); conductors: exact Fresnel (as
# normal-incidence constants: blue mean -2.1%); envmap: a map with a sun rotated by to_world;
# thin_dielectric: R' = 2R / (1 + R) (one surface's R: means -3.2 to -4.1%); emissive_mesh: area
# emitters on meshes sampled by NEE (BSDF sampling only: SSIM 0.88); rough_dielectric: GGX glass
# (means within 0.11%, SSIM 0.984); plastics (means within 0.01%, SSIM 0.996); textures;
# textured_roughness (a checkerboard alpha, its colours not swapped for eval_1: means -5%);
# normal_map (shaded unmirrored: means -1.5 to -2.4%); mask (checkerboard unswapped: SSIM 0.64);
# blend (a blendbsdf of each kind: means within 0.36%, SSIM 0.994; constant weights swapped: green -3.9%);
# mesh_attributes (vertex colours and a blend by face weights of a PLY: means within 0.07%, SSIM 0.999);
# textured_emission (checkerboard radiance on a turned sphere and an OBJ ball, sampled by NEE).


@pytest.mark.parametrize("name", CASES)
def test_path_integrator_agrees_with_mitsuba(name):
    """Box filter, same camera, Mitsuba at 8x wrt's spp, the images converged enough that noise
    no longer dominates SSIM: every channel's image mean within 2% (measured: under 0.4%) and
    SSIM of the tone-mapped images above 0.98 at full resolution (measured 0.986-0.999). wrt
    renders with its Sobol sampler, Mitsuba with its independent one: samplers change the noise
    only. Mitsuba's image is the stored one (``wrt_harness.mitsuba_suite.CROSSCHECKS``)."""
    check = CROSSCHECKS[name]
    scene = override_render(wrt.load_scene(check.path), width=check.width, height=check.height, sampler="sobol")
    ours = wrt.render(scene, spp=check.spp).rgb.astype(np.float64)
    theirs = check.image()
    assert ours.shape == theirs.shape and np.isfinite(ours).all()
    mean_ours, mean_theirs = ours.mean(axis=(0, 1)), theirs.mean(axis=(0, 1))
    np.testing.assert_allclose(mean_ours, mean_theirs, rtol=0.02)
    assert ssim(ours.astype(np.float32), theirs.astype(np.float32)) > 0.98
