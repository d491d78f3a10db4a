"""Benchmarks: each runs as ``python -m benchmarks.<name>``. Its default configuration writes
``benchmarks/results/<name>.{md,json}``, another configuration it declares ``benchmarks/results/<that one's name>.*``,
any other ``--out FOLDER`` or ``runs/benchmarks/<derived from the configuration>/`` (the rule: benchmarks/common.py)."""

import os

# headless rendering (contact sheets, videos) before anything imports mujoco: without a display, MuJoCo's default
# GLFW context fails, and it did so at the end of a benchmark run as `python -m benchmarks.bioloid_cpg_experiments`
os.environ.setdefault("MUJOCO_GL", "egl")
