"""A user who installs the wheel (not editable) and works from another folder can make every env."""

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import gymnasium as gym

import envs  # noqa: F401

ROOT = Path(__file__).resolve().parents[1]
PROBE = """
import json, sys
import gymnasium as gym
import numpy as np
import envs, agents, assets
from agents import load_policy, reference_policy
out = {"envs": envs.__file__, "assets": str(assets.ROOT), "made": []}
for env_id in sorted(k for k in gym.registry if k.startswith("skitter/")):
    env = gym.make(env_id)
    obs, _ = env.reset(seed=0)
    policy = load_policy(reference_policy(env.unwrapped.robot.name), env)
    obs, reward, *_ = env.step(policy.predict(obs)[0])
    assert np.isfinite(obs).all() and np.isfinite(reward)
    out["made"].append(env_id)
json.dump(out, sys.stdout)
"""


def test_the_wheel_holds_the_models_and_every_env_runs_from_it(tmp_path):
    wheels, site, elsewhere = tmp_path / "wheels", tmp_path / "site", tmp_path / "elsewhere"
    elsewhere.mkdir()
    source = tmp_path / "source"  # a copy, so that building leaves nothing in the checkout
    ignore = shutil.ignore_patterns("__pycache__", "*.egg-info", "build")
    for part in ("envs", "agents", "assets"):
        shutil.copytree(ROOT / part, source / part, ignore=ignore)
    for part in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / part, source / part)
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    build = subprocess.run(
        [*pip, "wheel", str(source), "--no-deps", "--no-build-isolation", "-w", str(wheels)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert build.returncode == 0, build.stderr
    (wheel,) = wheels.glob("skitter-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert "assets/velociroach/velociroach.xml" in names and "assets/bench/rig.xml" in names
    assert "agents/velociroach/turn_table.json" in names
    install = subprocess.run(
        [*pip, "install", "--no-deps", "--target", str(site), str(wheel)], capture_output=True, text=True, timeout=600
    )
    assert install.returncode == 0, install.stderr
    env = {**os.environ, "PYTHONPATH": str(site)}
    probe = subprocess.run(
        [sys.executable, "-c", PROBE], cwd=elsewhere, env=env, capture_output=True, text=True, timeout=600
    )
    assert probe.returncode == 0, probe.stderr
    found = json.loads(probe.stdout)
    assert Path(found["envs"]).is_relative_to(site), "the installed copy, not the checkout, was imported"
    assert Path(found["assets"]).is_relative_to(site)
    assert found["made"] == sorted(k for k in gym.registry if k.startswith("skitter/"))


def _pins() -> dict[str, str]:
    """constraints.txt as {canonical name: pinned version}."""
    from packaging.utils import canonicalize_name

    pins = {}
    for line in (ROOT / "constraints.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, _, version = line.partition("==")
            assert version, f"constraints.txt: {line!r} is not name==version"
            pins[canonicalize_name(name)] = version
    return pins


def test_constraints_pin_every_dependency_inside_its_range():
    """make installs constraints.txt's versions: each dependency and dev tool of pyproject.toml is pinned there, at
    a version its range admits, so the pins never fight the ranges."""
    import tomllib

    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    pins = _pins()
    for text in project["dependencies"] + project["optional-dependencies"]["dev"]:
        requirement = Requirement(text)
        name = canonicalize_name(requirement.name)
        assert name in pins, f"constraints.txt pins no version of {requirement.name}"
        assert requirement.specifier.contains(pins[name], prereleases=True), (
            f"constraints.txt pins {requirement.name}=={pins[name]}, outside pyproject.toml's {requirement}"
        )
    assert pins["torch"] == "2.13.0"  # the machine's CPU wheel, which the Makefile installs first
    assert "-c $(CONSTRAINTS)" in (ROOT / "Makefile").read_text()


def test_constraints_are_the_versions_the_leaderboard_rows_ran_on():
    """Every leaderboard row that records its libraries trained on the pinned ones, so a fresh clone's `make`
    installs what reproduces it (a row trained on other versions would need its own set)."""
    from packaging.version import Version

    from agents.leaderboard import LIBRARIES

    pins = _pins()
    records = sorted((ROOT / "docs/results/records/rows").glob("*/row.json"))
    recorded = [r for r in records if json.loads(r.read_text()).get("software")]
    assert recorded, "no leaderboard row records its libraries"
    for path in recorded:
        software = json.loads(path.read_text())["software"]
        for name in (k for k in LIBRARIES if k != "python"):  # what a row's record names besides the code
            assert Version(software[name]).public == Version(pins[name]).public, (
                f"{path.parent.name} trained on {name} {software[name]}, constraints.txt pins {pins[name]}"
            )
