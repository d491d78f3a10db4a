import contextlib
import io
import os
import subprocess
from collections.abc import Callable

os.environ.setdefault("MUJOCO_GL", "egl")

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import envs  # noqa: F401  (registers the envs)

ENV_IDS = sorted(env_id for env_id in gym.registry if env_id.startswith("skitter/"))


def model_bytes(model: mujoco.MjModel) -> bytes:
    """A compiled model as MuJoCo saves it: two models are the same model when these bytes are equal."""
    buffer = np.zeros(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer.tobytes()


def main_in_process(main: Callable[[list[str]], int], argv: list[str]) -> subprocess.CompletedProcess:
    """A command's ``main(argv)`` in the test's process, its exit code (argparse's own exits included) and what it
    printed, as ``subprocess.run`` gives them: the inputs a command refuses before anything runs, without a new
    process loading torch for each case (the tests of the command line itself start one)."""
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code
    return subprocess.CompletedProcess(argv, code, stdout.getvalue(), stderr.getvalue())


@pytest.fixture(autouse=True, scope="session")
def _sb3_logs_in_tmp_path(tmp_path_factory):
    """SB3's default logger (a ``learn()`` without ``tensorboard_log``) makes a dated folder in the system's temp
    directory unless ``SB3_LOGDIR`` names one: one folder in pytest's temporary tree for the whole session."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("SB3_LOGDIR", str(tmp_path_factory.mktemp("sb3")))
        yield


@pytest.fixture(params=ENV_IDS)
def env_id(request) -> str:
    return request.param


@pytest.hookimpl(tryfirst=True)  # before xdist's own hook, which reads the groups into the tests' ids
def pytest_collection_modifyitems(config, items):
    """Under ``pytest -n 2 --dist loadgroup`` (``make test``): the tests that share a module-scoped fixture (a
    trained run, a compiled model) run on one worker, so that the fixture is made once, not once per worker."""
    for item in items:
        info = getattr(item, "_fixtureinfo", None)
        if info is None:
            continue
        shared = sorted(
            name
            for name, defs in info.name2fixturedefs.items()
            if defs and defs[-1].scope == "module" and name in item.fixturenames
        )
        if shared:
            item.add_marker(pytest.mark.xdist_group(f"{item.module.__name__}::{shared[0]}"))
