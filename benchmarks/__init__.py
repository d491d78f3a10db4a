"""Benchmarks: each runs as ``python -m benchmarks.<name>`` and writes ``benchmarks/results/<name>.{md,json}``."""

import os

# headless rendering (contact sheets, videos) before anything imports mujoco: without a display, MuJoCo's default
# GLFW context fails, and it did so at the end of a benchmark run as `python -m benchmarks.bioloid_cpg_experiments`
os.environ.setdefault("MUJOCO_GL", "egl")
