"""PPO training throughput on RoachWalk: env steps per second including the updates, SB3's DummyVecEnv against the
batched env (agents/vec_env.py), the same hyperparameters (hyperparams/ppo.yml), in one run.

The first training demo's DummyVecEnv trained at 865 steps/s on this machine. Run:
``python -m benchmarks.train_speed``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

import envs  # noqa: F401
from agents.training import HYPERPARAMS_DIR, TORCH_THREADS, build_model, load_hyperparams, make_env
from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser, at_least_one

FIRST_DEMO_DUMMY = 865.0  # steps/s, the first training demo (DummyVecEnv, same hyperparameters)


def throughput(env_id: str, vec_env: str, steps: int, n_envs: int | None) -> float:
    overrides = {"vec_env": vec_env, **({"n_envs": n_envs} if n_envs else {})}
    hp = load_hyperparams(Path(HYPERPARAMS_DIR / "ppo.yml"), env_id, "ppo", overrides)
    model = build_model("ppo", hp, make_env(env_id, hp, seed=0), seed=0)
    torch.set_num_threads(TORCH_THREADS)
    t0 = time.perf_counter()
    model.learn(steps)
    return model.num_timesteps / (time.perf_counter() - t0)


CONFIGURATIONS: dict[str, list[str]] = {"train_speed": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--env", default="skitter/RoachWalk-v4")
    parser.add_argument("--steps", type=at_least_one, default=40960)
    parser.add_argument("--n-envs", type=at_least_one, nargs="+", default=[4, 16])
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "train_speed", CONFIGURATIONS)
    rows = []
    for n in args.n_envs:
        dummy = throughput(args.env, "dummy", args.steps, n)
        batched = throughput(args.env, "batched", args.steps, n)
        rows.append({"n_envs": n, "dummy_steps_per_s": dummy, "batched_steps_per_s": batched})
        print(rows[-1])
    table = md_table(
        ["n_envs", "DummyVecEnv steps/s", "batched steps/s", "batched / DummyVecEnv", "batched / the first demo's 865"],
        [[r["n_envs"], round(r["dummy_steps_per_s"]), round(r["batched_steps_per_s"]),
          round(r["batched_steps_per_s"] / r["dummy_steps_per_s"], 2),
          round(r["batched_steps_per_s"] / FIRST_DEMO_DUMMY, 2)] for r in rows],
    )  # fmt: skip
    text = (
        f"# PPO training throughput on {args.env} (env steps per second, updates included)\n\n"
        f"{args.steps} steps per run, hyperparameters of hyperparams/ppo.yml with n_envs as given (n_steps 512 per "
        "env, 10 epochs, minibatches of 256, a 64x64 MLP on one torch thread).\n\n" + table
    )
    output.save({"env": args.env, "steps": args.steps, "rows": rows}, text)


if __name__ == "__main__":
    main()
