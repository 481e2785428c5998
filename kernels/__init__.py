"""Warp device code of wrt: ``@wp.func`` building blocks and the ``@wp.kernel`` integrators.

Modules, in data-flow order:

- ``sampling``  counter-based random numbers (deterministic per pixel, sample, dimension)
- ``camera``    pinhole camera rays
- ``intersect`` ray-primitive tests (plane, sphere, triangle, polygon, box)
- ``scene``     the device-side scene layout (``SceneData``) and BVH traversal
- ``raycast``   the "raycast" integrator kernel

This package imports only Warp: it knows nothing of scene files, images or the harness.
Importing it configures Warp for rendering: no gradients (smaller, faster modules) and
no informational log lines on the console.
"""
import warp as wp

wp.config.enable_backward = False
wp.config.log_level = wp.LOG_WARNING
