"""The documentation as a user reads it: a README of bounded size whose env table matches the registry and whose
benchmark numbers are found in the current results of the benchmark each row's command names; docs/envs.md and the
changelog name every registered env."""

import re
from pathlib import Path

import gymnasium as gym
import pytest
from gymnasium.wrappers import TimeLimit

from tests.conftest import ENV_IDS

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
RESULTS = ROOT / "benchmarks" / "results"
NUMBER = re.compile(r"(?<![\d.])\d+(?:\.\d+)?(?![\d.])")  # 2.21 of "2.21x", 40 of "40 min"


def _rows(text: str, header_start: str) -> list[list[str]]:
    """The body rows of the Markdown table whose header row starts with ``header_start``, as lists of cells."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(header_start))
    rows = []
    for line in lines[start + 2 :]:
        if not line.startswith("|"):
            break
        rows.append([cell.strip() for cell in line.strip().strip("|").split("|")])
    return rows


def _time_limit(env: gym.Env) -> int | None:
    """The steps of the first time limit in the wrapper chain (set by the registration or by the entry point)."""
    while isinstance(env, gym.Wrapper):
        if isinstance(env, TimeLimit):
            return env._max_episode_steps
        env = env.env
    return None


def _numbers(text: str) -> set[float]:
    return {float(n) for n in NUMBER.findall(text.replace(",", ""))}


def test_readme_is_a_front_page():
    """At most about 15 KB, and no line over 120 characters outside tables and code blocks."""
    text = README.read_text(encoding="utf-8")
    assert len(text.encode("utf-8")) <= 16_000, len(text.encode("utf-8"))
    long_lines, in_code = [], False
    for number, line in enumerate(text.splitlines(), 1):
        if line.startswith("```"):
            in_code = not in_code
        elif not in_code and not line.startswith("|") and len(line) > 120:
            long_lines.append(number)
    assert not long_lines, f"README.md lines over 120 characters: {long_lines}"


@pytest.mark.parametrize("doc", ["README.md", "docs/envs.md"])
def test_every_registered_env_is_in_the_env_table(doc):
    ids = {row[0].strip("`") for row in _rows((ROOT / doc).read_text(encoding="utf-8"), "| id |")}
    assert ids == set(ENV_IDS), f"{doc}: missing {sorted(set(ENV_IDS) - ids)}, unknown {sorted(ids - set(ENV_IDS))}"


def test_readme_env_table_matches_the_envs():
    """Observation size, control rate and episode length as the registered envs have them."""
    for env_id, _robot, _task, _action, control, obs, episode in _rows(README.read_text(encoding="utf-8"), "| id |"):
        env = gym.make(env_id.strip("`"))
        try:
            rate = 1.0 / env.unwrapped.dt
            quoted = float(control.split()[0]) * (1000.0 if "kHz" in control else 1.0)
            assert abs(rate - quoted) < 1e-6, (env_id, control, rate)
            assert int(obs) == env.observation_space.shape[0], (env_id, obs, env.observation_space.shape)
            steps = int(re.search(r"\((\d+) steps\)", episode).group(1))
            assert steps == round(float(episode.split()[0]) * rate) == _time_limit(env), (env_id, episode)
        finally:
            env.close()


def test_readme_benchmark_numbers_come_from_the_current_results():
    """Each row's number is in a results file (benchmarks/results/<module>*.md) of the module its command runs."""
    rows = _rows(README.read_text(encoding="utf-8"), "| benchmark | current |")
    assert len(rows) >= 10
    module = None
    for benchmark, current, _goal, _verdict, command in rows:
        named = re.search(r"python -m benchmarks\.(\w+)", command)
        if named:
            module = named.group(1)
        else:
            assert command == "same" and module is not None, f"README row {benchmark!r}: no benchmark command"
        files = sorted(RESULTS.glob(f"{module}*.md"))
        assert files, f"no results of benchmarks.{module} for the README row {benchmark!r}"
        found = set().union(*(_numbers(f.read_text(encoding="utf-8")) for f in files))
        wanted = _numbers(current)
        assert wanted, f"the README row {benchmark!r} gives no number"
        missing = wanted - found
        assert not missing, f"README row {benchmark!r}: {sorted(missing)} not in benchmarks/results/{module}*.md"


def test_changelog_names_every_registered_env():
    """The changelog records env versions: every registered id (with its version) appears in it."""
    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    assert text.startswith("# Changelog") and "## [Unreleased]" in text
    missing = [env_id for env_id in ENV_IDS if f"`{env_id}`" not in text]
    assert not missing, f"CHANGELOG.md does not name {missing}"
