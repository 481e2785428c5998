#!/usr/bin/env bash
# GPU readiness in one call (benchmarks/gpu_check.py says what it runs): the device-parametrised
# tests, `wrt matrix`, CPU against GPU images of every matrix entry, the throughput and path
# benchmarks, then a short report (default benchmarks/results/gpu_check.md). Needs the project
# installed with its test extra (pip install -e '.[test]'). Under 8 minutes on an H200.
#   benchmarks/gpu_check.sh                          # on a CUDA machine (--device cuda)
#   benchmarks/gpu_check.sh --device cpu --quick     # a dry run of the script, anywhere
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
export VTK_DEFAULT_OPENGL_WINDOW="${VTK_DEFAULT_OPENGL_WINDOW:-vtkEGLRenderWindow}"  # no display: EGL
exec python3 -m wrt_benchmarks.gpu_check "$@"
