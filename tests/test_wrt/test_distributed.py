"""wrt.distributed: renders, references and matrix entries on a Dask ``LocalCluster`` of two
worker processes are bit-identical to local runs, ship everything a worker needs, and build
each scene and load each kernel once per worker."""

from __future__ import annotations

import json
import shutil
import sys
from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("distributed")

from conftest import EXAMPLES  # noqa: E402
from wrt_harness import references  # noqa: E402
from wrt_harness.matrix import load_features, select  # noqa: E402
from wrt_harness.run import evaluate  # noqa: E402

import wrt  # noqa: E402
import wrt.distributed as wd  # noqa: E402
from wrt.cli import main  # noqa: E402
from wrt.errors import WrtError  # noqa: E402
from wrt.imageio import read_image  # noqa: E402
from wrt.loader import override_render  # noqa: E402

SCENE = EXAMPLES / "path" / "emissive_mesh.toml"  # three mesh files: OBJ and STL
# one LocalCluster for the module: under pytest-xdist, with --dist loadgroup, all its tests go to one worker
pytestmark = pytest.mark.xdist_group("dask_local_cluster")


@pytest.fixture(scope="module")
def cluster():
    from distributed import LocalCluster

    with (
        LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as local,
        wd.Cluster(local.scheduler_address) as connected,
    ):
        yield connected


@pytest.fixture
def shipped_scene(tmp_path):
    """The example scene loaded from a copy whose mesh files are deleted once it is parsed: a
    worker that read a file would fail."""
    shutil.copytree(EXAMPLES / "meshes", tmp_path / "meshes")
    (tmp_path / "path").mkdir()
    shutil.copy(SCENE, tmp_path / "path" / SCENE.name)
    scene = wrt.load_scene(str(tmp_path / "path" / SCENE.name))
    shutil.rmtree(tmp_path / "meshes")
    return override_render(scene, width=32, height=24)


def assert_same(a: wrt.RenderResult, b: wrt.RenderResult) -> None:
    assert a.spp == b.spp and a.rejected_samples == b.rejected_samples
    np.testing.assert_array_equal(a.rgb, b.rgb)
    assert a.aovs.keys() == b.aovs.keys()
    for name in a.aovs:
        np.testing.assert_array_equal(a.aovs[name], b.aovs[name], err_msg=name)


def test_tiles_and_passes_are_bit_identical_to_a_local_render(cluster, shipped_scene):
    passes = []
    tiled = cluster.render(shipped_scene, spp=5, seed=3, progress=lambda done, *rest: passes.append(done))
    assert len(passes) > 1 and passes[-1] == 5  # several passes, each continuing the tiles' sums
    assert shipped_scene.render.width * shipped_scene.render.height > wd.MIN_TILE_PIXELS  # several tiles
    assert_same(tiled, wrt.render(shipped_scene, spp=5, seed=3))
    assert_same(tiled, wrt.render(shipped_scene, spp=5, seed=3, threads=1))
    assert tiled.rgb.std() > 0.01  # a real image, not two equal blanks


def test_a_worker_builds_a_scene_and_loads_a_kernel_once(cluster, shipped_scene):
    before = cluster.client.run(wd.worker_stats)
    results = [cluster.render(shipped_scene, spp=spp, seed=spp) for spp in (1, 2, 3, 4)]  # 3 tiles each
    after = cluster.client.run(wd.worker_stats)
    assert len(after) == 2
    for worker, stats in after.items():
        assert stats["scenes_prepared"] - before[worker]["scenes_prepared"] <= 1, worker
        assert stats["kernel_loads"] - before[worker]["kernel_loads"] <= 1, worker
    assert results[-1].build_time_s == 0.0 and results[-1].compile_time_s == 0.0


def test_wrt_render_on_the_scheduler_writes_the_local_image(cluster, tmp_path):
    common = [str(SCENE), "--width", "32", "--height", "24", "--spp", "3", "--aov", "all"]
    assert main(["render", *common, "-o", str(tmp_path / "local.exr")]) == 0
    assert main(["render", *common, "-o", str(tmp_path / "cluster.exr"), "--scheduler", cluster.address]) == 0
    local, remote = read_image(str(tmp_path / "local.exr")), read_image(str(tmp_path / "cluster.exr"))
    np.testing.assert_array_equal(remote.rgb, local.rgb)
    assert remote.aovs.keys() == local.aovs.keys()
    for name in local.aovs:
        np.testing.assert_array_equal(remote.aovs[name], local.aovs[name], err_msg=name)


@pytest.mark.parametrize(
    "address, words", [("nonsense", "not a scheduler address"), ("tcp://127.0.0.1:9", "cannot connect")]
)
def test_an_unreachable_scheduler_is_one_error_line(tmp_path, capsys, monkeypatch, address, words):
    monkeypatch.setattr(wd, "CONNECT_TIMEOUT_S", 0.5)
    out = tmp_path / "out.exr"
    assert main(["render", str(SCENE), "--width", "8", "--height", "8", "-o", str(out), "--scheduler", address]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"wrt: error: --scheduler {address}: {words}"), err
    assert not out.exists()


def test_without_dask_the_scheduler_option_names_the_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed: ImportError
    out = tmp_path / "out.exr"
    assert main(["render", str(SCENE), "-o", str(out), "--scheduler", "tcp://127.0.0.1:9"]) == 2
    assert "pip install 'wrt[cluster]'" in capsys.readouterr().err and not out.exists()


def test_a_reference_and_its_calibration_are_bit_identical(cluster):
    feature = replace(select(load_features(), ["emissive_mesh"])[0], width=32, height=24)
    local = references.render_reference(feature, spp=32)
    remote = references.render_reference(feature, spp=32, cluster=cluster)  # 32 batches, one task each
    np.testing.assert_array_equal(remote.rgb, local.rgb)
    np.testing.assert_array_equal(remote.variance, local.variance)
    assert remote.spp == local.spp == 32 and local.variance.max() > 0.0
    assert references.calibrate(feature, local, cluster=cluster) == references.calibrate(feature, local)


def test_a_matrix_entry_is_one_task_with_the_local_scores(cluster):
    feature = select(load_features(), ["raycast_mesh"])[0]
    local, remote = evaluate(feature), evaluate(feature, cluster=cluster)
    assert local.passed and remote.passed
    for key in ("ssim", "z", "geometry_ssim", "rmse", "max_error", "failures"):
        assert getattr(remote, key) == getattr(local, key), key
    for name, image in local.images.items():
        np.testing.assert_array_equal(remote.images[name], image, err_msg=name)


def test_wrt_refs_regenerate_and_wrt_matrix_on_the_scheduler(cluster, tmp_path, capsys):
    for folder, options in (("local", []), ("cluster", ["--scheduler", cluster.address])):
        assert main(["refs", "regenerate", "raycast_mesh", "--refs", str(tmp_path / folder), *options]) == 0
    local, remote = (read_image(str(tmp_path / folder / "raycast_mesh.exr")) for folder in ("local", "cluster"))
    np.testing.assert_array_equal(remote.rgb, local.rgb)
    np.testing.assert_array_equal(remote.aovs["variance"], local.aovs["variance"])
    assert remote.metadata == local.metadata
    calibrations = [json.loads((tmp_path / f / "raycast_mesh.json").read_text()) for f in ("local", "cluster")]
    for calibration in calibrations:
        calibration.pop("reference_sha256")  # of the EXR file, whose header has a time stamp
    assert calibrations[0] == calibrations[1]
    capsys.readouterr()
    assert main(["matrix", "raycast_mesh", "--refs", str(tmp_path / "cluster"), "--scheduler", cluster.address]) == 0
    assert "1 passed, 0 failed" in capsys.readouterr().out


def test_a_worker_error_reaches_the_client(cluster, shipped_scene):
    with pytest.raises(WrtError, match="no CUDA device|device 'nowhere'"):
        cluster.render(shipped_scene, spp=1, device="nowhere")
