"""pyvista/VTK must render off screen on a headless machine (no X server, no GPU).

The render runs in a child process: when no OpenGL backend can be loaded, the VTK 9.7
wheel can crash the interpreter (SIGSEGV) instead of raising, and that must turn into a
test failure with instructions, not a dead test run.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import numpy as np

APT_HINT = (
    "Off-screen rendering with pyvista/VTK is not available. On Debian 12 install the EGL + "
    "Mesa software renderer: `apt-get install -y --no-install-recommends libegl1 libgl1-mesa-dri` "
    "(`.ci/run` does this) and set VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow when there is no "
    "display. Alternative: `libosmesa6` with VTK_DEFAULT_OPENGL_WINDOW=vtkOSOpenGLRenderWindow. "
    "See docs/install-notes.md."
)

CHILD = textwrap.dedent(
    """
    import sys
    import numpy as np
    import pyvista as pv

    pv.OFF_SCREEN = True
    plotter = pv.Plotter(off_screen=True, window_size=(64, 48))
    plotter.set_background("white")
    plotter.add_mesh(pv.Sphere(radius=0.5), color="red")
    img = plotter.screenshot(return_img=True)
    print("render window:", type(plotter.ren_win).__name__, file=sys.stderr)
    plotter.close()
    np.save(sys.argv[1], np.asarray(img))
    """
)


def test_offscreen_sphere_is_not_blank(tmp_path):
    out = tmp_path / "sphere.npy"
    try:
        proc = subprocess.run(
            [sys.executable, "-c", CHILD, str(out)],
            capture_output=True,
            text=True,
            timeout=180,
            env=os.environ.copy(),
        )
    except subprocess.TimeoutExpired as exc:
        raise AssertionError(f"off-screen render hung for {exc.timeout}s. {APT_HINT}") from None
    if proc.returncode != 0 or not out.exists():
        how = f"exit code {proc.returncode}"
        if proc.returncode < 0:
            how = f"killed by {signal.Signals(-proc.returncode).name}"
        raise AssertionError(
            f"off-screen render failed ({how}). {APT_HINT}\n"
            f"VTK_DEFAULT_OPENGL_WINDOW={os.environ.get('VTK_DEFAULT_OPENGL_WINDOW')!r}\n"
            f"--- child stderr (tail) ---\n{proc.stderr[-3000:]}"
        )

    img = np.load(out)
    assert img.shape[:2] == (48, 64), img.shape
    colours = np.unique(img.reshape(-1, img.shape[-1]), axis=0)
    assert len(colours) > 2, f"blank image: only {len(colours)} distinct colours. {APT_HINT}"
    centre, corner = img[24, 32], img[0, 0]
    assert not np.array_equal(centre, corner), (
        f"centre pixel {centre} equals corner pixel {corner}: the sphere was not drawn. {APT_HINT}"
    )
    assert centre[0] > centre[1] and centre[0] > centre[2], f"centre pixel {centre} is not red"
