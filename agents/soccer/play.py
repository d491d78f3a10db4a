"""Matches between two teams' policies with honest statistics: the soccer half of ``evaluate.py``.

    python evaluate.py --soccer bioloid --players 3 --home scripted --away random --matches 20 --seed 0 \\
        --out results/scripted_vs_random [--video] [--match-seconds 60] [--action-mode commands]

Match ``i`` runs with seed ``SEED + i`` (the PettingZoo match ``envs.soccer.match.parallel_env(...)`` reset with that
seed, bit for bit; all matches are stepped together on one ``mujoco.batch``). A team's policy is ``scripted`` (the
scripted team, commands mode), ``random`` (uniform actions, each match's own stream from its seed) or a model of
``train.py --soccer``. Printed and written to DIR/results.json and DIR/results.md: the home team's wins, draws and
losses with 95% Wilson intervals, and the mean goal difference (home minus away) with a 95% bootstrap interval;
with --video, DIR/videos/match.mp4 of the first match from the top camera. The results are written as one unit (a
temporary folder that takes DIR's place), and bad arguments are refused in one line before any match runs.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from agents.evaluation import wilson_interval
from envs.common.io import (
    ToolParser,
    publish_folder,
    published_exit_code,
    replace_problem,
    results_folder_problem,
    results_foreign,
    run_interruptibly,
    unpublished_exit_code,
    write_json,
    write_text,
)
from envs.soccer.match import MATCH_SECONDS, MAX_PLAYERS, Matches, action_modes
from envs.soccer.robots import BY_NAME
from envs.soccer.scripted import ScriptedTeam, scripted_team
from envs.soccer.steering import COMMANDS

TEAMS = ("scripted", "random")
RESULT_FILES = ("results.json", "results.md")


class TeamPolicy:
    """One team's actions for every match at once: ``act(obs) -> actions`` for the team's rows."""

    def __init__(self, spec: str, engine: Matches, team: str, seed: int):
        self.spec, self.team = spec, team
        agents = [a for a in engine.possible_agents if a.startswith(team)]
        self.agent_index = [engine.possible_agents.index(a) for a in agents]
        self.rows = [engine.rows_of(np.arange(engine.num_matches)).reshape(engine.num_matches, -1)[:, i]
                     for i in self.agent_index]  # fmt: skip
        self.residual = None  # a residual team's correction scale on the scripted team (agents/soccer/selfplay.py)
        if spec not in TEAMS:
            self.model = trained_team(spec, engine)
            self.residual = residual_scale(spec, self.model.manifest)
        if spec == "scripted" or self.residual is not None:
            self.script = ScriptedTeam(list(scripted_team(engine, team).values()))  # in the order of ``agents``
            self.memory: np.ndarray | None = None  # each match's players' (matches, players, len(MEMORY))
            self.grid = np.stack(self.rows, axis=1)  # each match's row of each player (matches, players)
        if spec == "random":
            # each match's own stream, from that match's seed: match i of SEED replays as match 0 of SEED + i
            self.rngs = [np.random.default_rng([seed + m, 0 if team == "home" else 1])
                         for m in range(engine.num_matches)]  # fmt: skip
        self.size = engine.mode.size

    def act(self, obs: np.ndarray, actions: np.ndarray) -> None:
        """Write the team's actions into ``actions`` (rows, size) from the observations (rows, size)."""
        if self.spec == "scripted" or self.residual is not None:
            actions[self.grid], self.memory = self.script.act(obs[self.grid], self.memory)
            if self.spec == "scripted":
                return
        if self.spec not in TEAMS:  # one shared policy for every player of the team, every match in one call
            rows = np.concatenate(self.rows)
            own = self.model.predict(obs[rows], deterministic=True)[0]
            if self.residual is not None:  # a correction of the scripted commands just written
                own = actions[rows] + self.residual * np.asarray(own, np.float64)
            actions[rows] = np.clip(own, -1.0, 1.0)
            return
        for m, rng in enumerate(self.rngs):
            actions[[rows[m] for rows in self.rows]] = rng.uniform(-1.0, 1.0, (len(self.rows), self.size))


def trained_team(path: str, engine: Matches):
    """A team policy trained by ``train.py --soccer`` (or any SB3 model of the match's observation and action
    sizes), as an :class:`agents.sb3.SB3Policy`; ValueError if it was trained for another match."""
    from agents.sb3 import SB3Policy

    policy = SB3Policy(path)
    soccer = policy.manifest.get("soccer")
    if soccer is not None:
        want = {"robot": engine.robot_name, "players_per_team": engine.players // 2, "action_mode": engine.action_mode}
        wrong = {k: soccer.get(k) for k, v in want.items() if soccer.get(k) != v}
        if wrong:
            raise ValueError(f"{path}: the team was trained with {wrong}, this match has {want}")
    size, actions = policy.model.observation_space.shape, policy.model.action_space.shape
    if size != (engine.task.layout.size,) or actions != (engine.mode.size,):
        raise ValueError(f"{path}: the model takes {size} observations and gives {actions} actions; this match's "
                         f"players have {engine.task.layout.size} and {engine.mode.size}")  # fmt: skip
    return policy


def residual_scale(path: str, manifest: dict[str, Any]) -> float | None:
    """A trained team's correction scale, if it plays on top of the scripted team (``train.py --soccer ROBOT
    --residual scripted``); ValueError for a residual on anything else."""
    from agents.residual import parse_residual
    from agents.soccer.selfplay import SCRIPTED

    record = manifest.get("residual")
    if record is None:
        return None
    residual = parse_residual(record)
    if residual.policy != SCRIPTED:
        raise ValueError(f"{path}: a residual policy on {residual.policy!r}, which plays one robot's env, not a team")
    return residual.scale


def team_mode(spec: str) -> str | None:
    """The action mode a team's policy plays in: the scripted team's and a self-play model's is ``commands``."""
    if spec == "scripted":
        return COMMANDS
    if spec in TEAMS:
        return None
    from agents.sb3 import read_model_file

    manifest, _ = read_model_file(spec)
    soccer = (manifest or {}).get("soccer") or {}
    return soccer.get("action_mode")


def prepare(robot: str, players: int, home: str, away: str, matches: int, seed: int, match_seconds: float,
            action_mode: str | None = None, kick: bool = False) -> tuple[Matches, list[TeamPolicy]]:  # fmt: skip
    """The seeded matches, reset, and the two teams (:func:`play`'s arguments); ValueError, before anything is
    written, for teams that cannot play each other or these matches."""
    modes = {m for m in (team_mode(home), team_mode(away)) if m is not None}
    if len(modes) > 1:
        raise ValueError(f"the two teams play in different action modes: {sorted(modes)}")
    if action_mode is not None and modes and action_mode not in modes:
        raise ValueError(f"--action-mode {action_mode!r}: the teams play in {modes.pop()!r}")
    mode = action_mode if action_mode is not None else (modes.pop() if modes else None)
    if kick and mode != COMMANDS:
        playing = f"the {mode!r} mode" if mode else "the robot's own mode (give --action-mode commands)"
        raise ValueError(f"--kick is the {COMMANDS!r} mode's kick action: the teams play in {playing}")
    engine = Matches(robot=robot, players_per_team=players, action_mode=mode, num_matches=matches, batched=True,
                     max_cycles=1, kick=kick)  # fmt: skip
    engine.max_cycles = max(1, round(match_seconds / engine.dt))
    for m in range(matches):
        engine.seed(m, seed + m)
    engine.reset(np.arange(matches))
    return engine, [TeamPolicy(home, engine, "home", seed), TeamPolicy(away, engine, "away", seed)]


def play(robot: str, players: int, home: str, away: str, matches: int, seed: int, match_seconds: float,
         action_mode: str | None = None, video: Path | None = None, kick: bool = False,
         prepared: tuple[Matches, list[TeamPolicy]] | None = None) -> dict[str, Any]:  # fmt: skip
    """Play ``matches`` seeded matches; returns every match's score and the statistics. A team is ``scripted``,
    ``random`` or the path of a model trained by ``train.py --soccer``; ``kick``: the commands mode's kick action
    (the Bioloid's), for both teams. ``prepared``: :func:`prepare`'s result for these arguments (made here if
    None). A match lasts a whole number of control steps: ``match_seconds`` rounded to one (at least one)."""
    engine, teams = prepared or prepare(robot, players, home, away, matches, seed, match_seconds, action_mode, kick)
    actions = np.zeros((engine.robot.num_sims, engine.mode.size))
    frames, renderer = [], None
    if video is not None:
        renderer = _renderer(engine)
    # a match whose scene goes numerically unstable (MuJoCo resets its data) is stopped there, as a referee would
    # abandon it: its score stands as it was, and the record says when; nothing after it counts
    stopped = np.full(matches, np.nan)
    final = np.zeros((matches, 2), dtype=np.int64)
    refined = np.zeros(matches, dtype=np.int64)  # steps that diverged and held when run again at shorter steps
    for cycle in range(engine.max_cycles):
        for team in teams:
            team.act(engine.obs, actions)
        out = engine.step(actions)
        refined += out["refined"] & np.isnan(stopped)
        new = out["unstable"] & np.isnan(stopped)
        if new.any():
            stopped[new] = (cycle + 1) * engine.dt
            final[new] = engine.scores[new]  # the unstable step's goals are not counted (Matches.step)
        if renderer is not None:
            frames.append(renderer.render(engine.scene.sim.get_data(0)))
    if renderer is not None:
        from agents.evaluation import write_video

        renderer.close()
        write_video(frames, video, fps=1.0 / engine.dt)
    played = np.isnan(stopped)
    final[played] = engine.scores[played]
    scores = final.tolist()
    cut = [{"match": int(m), "seed": seed + int(m), "seconds": float(stopped[m]), "score": scores[m]}
           for m in np.flatnonzero(~played)]  # fmt: skip
    return {"scores": scores, "played_seconds": engine.max_cycles * engine.dt, "stopped_unstable": cut,
            "refined_steps": refined.tolist(), **statistics(final)}  # fmt: skip


def _renderer(engine: Matches):
    import mujoco

    from envs.common.rendering import FrameRenderer
    from envs.soccer.field import TOP_CAMERA

    camera = mujoco.MjvCamera()
    camera.type, camera.fixedcamid = mujoco.mjtCamera.mjCAMERA_FIXED, engine.scene.model.camera(TOP_CAMERA).id
    return FrameRenderer(engine.scene.model, camera, 480, 360)


def statistics(scores: np.ndarray) -> dict[str, Any]:
    """The home team's wins, draws and losses (counts, fractions and 95% Wilson intervals) and the mean goal
    difference with a 95% bootstrap interval (percentile; the interval is the mean itself when every match had the
    same difference)."""
    diff = scores[:, 0] - scores[:, 1]
    n = len(diff)
    out: dict[str, Any] = {"matches": n}
    for name, count in (("wins", int((diff > 0).sum())), ("draws", int((diff == 0).sum())),
                        ("losses", int((diff < 0).sum()))):  # fmt: skip
        low, high = wilson_interval(count, n)
        out[name] = {"count": count, "fraction": count / n, "ci_low": low, "ci_high": high}
    mean = float(diff.mean())
    if n > 1 and np.ptp(diff) > 0:
        boot = stats.bootstrap((diff,), np.mean, confidence_level=0.95, method="percentile", random_state=0)
        low, high = float(boot.confidence_interval.low), float(boot.confidence_interval.high)
    else:
        low = high = mean
    out["goal_difference"] = {"mean": mean, "ci_low": low, "ci_high": high}
    out["goals"] = {"home": int(scores[:, 0].sum()), "away": int(scores[:, 1].sum())}
    return out


def report(args: argparse.Namespace, result: dict[str, Any]) -> str:
    row = [f"{result[k]['count']} ({100 * result[k]['fraction']:.0f}% [{100 * result[k]['ci_low']:.0f}, "
           f"{100 * result[k]['ci_high']:.0f}])" for k in ("wins", "draws", "losses")]  # fmt: skip
    gd = result["goal_difference"]
    return (
        f"# {args.soccer}, {args.players} a side: {args.home} (home) against {args.away} (away)\n\n"
        f"{result['matches']} matches of {result['played_seconds']:g} s, seeds "
        f"{args.seed}-{args.seed + args.matches - 1}; "
        "the home team's record, 95% Wilson intervals; goal difference home minus away, 95% bootstrap interval.\n\n"
        "| wins | draws | losses | goal difference | goals (home-away) |\n|---|---|---|---|---|\n"
        f"| {' | '.join(row)} | {gd['mean']:+.2f} [{gd['ci_low']:+.2f}, {gd['ci_high']:+.2f}] | "
        f"{result['goals']['home']}-{result['goals']['away']} |\n"
        + _stopped_note(args, result["stopped_unstable"])
        + _refined_note(result.get("refined_steps", []))
    )


def _refined_note(refined: list[int]) -> str:
    """The steps that diverged and were run again at shorter physics steps, where any were (docs/soccer.md)."""
    steps, matches = sum(refined), sum(1 for r in refined if r)
    if not steps:
        return ""
    return (f"\n{steps} control step{'s' * (steps != 1)} in {matches} match{'es' * (matches != 1)} diverged and "
            "held when run again at shorter physics steps; those matches went on.\n")  # fmt: skip


def _stopped_note(args: argparse.Namespace, stopped: list[dict[str, Any]]) -> str:
    """The matches stopped early, where a scene went numerically unstable (their scores stand as they were)."""
    if not stopped:
        return ""
    each = ", ".join(f"seed {s['seed']} at {s['seconds']:.1f} s ({s['score'][0]}-{s['score'][1]})"
                     for s in stopped)  # fmt: skip
    return (f"\n{len(stopped)} of {args.matches} matches went numerically unstable (MuJoCo reset the scene) and were "
            f"stopped there, their scores standing as they were: {each}.\n")  # fmt: skip


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = ToolParser(prog="evaluate.py --soccer", description="Play matches between two teams' policies.")
    p.add_argument("--soccer", required=True, choices=sorted(BY_NAME), help="the robot")
    p.add_argument("--players", type=int, default=3, help=f"players a side, 1 to {MAX_PLAYERS}")
    p.add_argument(
        "--home",
        required=True,
        help="the home team's policy: scripted, random, a model.zip, or a run or "
        "checkpoint folder of train.py --soccer (its model.zip)",
    )
    p.add_argument("--away", required=True, help="the away team's policy, as --home's")
    p.add_argument("--matches", type=int, default=20)
    p.add_argument("--seed", type=int, default=0, help="match i runs with seed SEED + i")
    p.add_argument("--match-seconds", type=float, default=MATCH_SECONDS, help="each match's length, s")
    p.add_argument("--action-mode", help="the robots' action mode (default: commands where a team is scripted)")
    p.add_argument("--kick", action="store_true", help="the commands mode's kick action, for a robot that kicks "
                   "(the Bioloid): both teams have it, and the scripted team kicks")  # fmt: skip
    p.add_argument("--out", required=True, type=Path, help="output directory")
    p.add_argument("--video", action="store_true", help="write an mp4 of the first match")
    p.add_argument("--overwrite", action="store_true", help="replace the results of an earlier run in --out")
    if argv is not None and ("-h" in argv or "--help" in argv):  # also as `--soccer --help`, before a robot is named
        p.print_help()
        p.exit()
    args = p.parse_args(argv)
    if not 1 <= args.players <= MAX_PLAYERS:
        p.error(f"--players must be from 1 to {MAX_PLAYERS}, got {args.players}")
    if args.matches < 1:
        p.error(f"--matches must be at least 1, got {args.matches}")
    if args.seed < 0:
        p.error(f"--seed must be >= 0, got {args.seed}")
    if not 0 < args.match_seconds <= 3600:
        p.error(f"--match-seconds must be in (0, 3600], got {args.match_seconds}")
    modes = action_modes(args.soccer)
    if args.action_mode is not None and args.action_mode not in modes:
        p.error(f"--action-mode must be one of {modes} for the {args.soccer}, got {args.action_mode!r}")
    if "scripted" in (args.home, args.away) and args.action_mode not in (None, COMMANDS):
        p.error(f"--action-mode {args.action_mode!r}: the scripted team plays in the {COMMANDS!r} mode")
    for name in ("home", "away"):
        spec = getattr(args, name)
        if spec in TEAMS:
            continue
        spec = model_in(spec)
        setattr(args, name, spec)
        problem = model_file_problem(spec)
        if problem:
            p.error(
                f"--{name} {spec!r}: {problem} (a team is scripted, random, or train.py --soccer's model.zip, "
                "run folder or checkpoint folder)"
            )
    problem = results_folder_problem(args.out, args.overwrite, "evaluate.py", _foreign(args.out))
    problem = problem or replace_problem(args.out)
    if problem:
        p.error(problem)
    args.out_existed = args.out.exists()
    return args


def model_in(spec: str) -> str:
    """A team given as a folder of ``train.py --soccer`` (a run, or one of its checkpoints) is its ``model.zip``."""
    folder = Path(spec)
    return str(folder / "model.zip") if folder.is_dir() and (folder / "model.zip").is_file() else spec


def model_file_problem(spec: str) -> str | None:
    """Why ``spec`` is not a readable model file, or None."""
    from agents.sb3 import ModelFileError, read_model_file

    try:
        read_model_file(spec)
    except ModelFileError as exc:
        return str(exc)
    return None


def _foreign(out: Path):
    """What in an entry of ``out`` evaluate.py --soccer does not write."""
    return results_foreign(out, RESULT_FILES, {"videos": ".mp4"})


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    return run_interruptibly("evaluate.py", args.out, lambda: _run(args))


def _run(args: argparse.Namespace) -> int:
    out: Path = args.out
    try:  # every refusal before anything is written
        prepared = prepare(args.soccer, args.players, args.home, args.away, args.matches, args.seed,
                           args.match_seconds, args.action_mode, args.kick)  # fmt: skip
    except ValueError as exc:
        print(f"evaluate.py --soccer: error: {exc}", file=sys.stderr)
        return 2
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f".{out.name}.", dir=out.parent) as tmp:
        staging = Path(tmp) / "results"
        staging.mkdir()
        video = staging / "videos" / "match.mp4" if args.video else None
        if video is not None:
            video.parent.mkdir()
        result = play(args.soccer, args.players, args.home, args.away, args.matches, args.seed, args.match_seconds,
                      args.action_mode, video, args.kick, prepared)  # fmt: skip
        text = report(args, result)
        record = {"robot": args.soccer, "players_per_team": args.players, "kick": args.kick, "home": args.home,
                  "away": args.away,
                  "seeds": [args.seed + i for i in range(args.matches)], "match_seconds": args.match_seconds,
                  **result}  # fmt: skip
        write_json(staging / "results.json", record, strict=True)
        write_text(staging / "results.md", text)
        try:
            where = publish_folder(staging, out, args.out_existed, _foreign(out))
        except OSError as exc:
            return unpublished_exit_code("evaluate.py", staging, out, exc)
    print(text)
    print(f"results in {where}/ (results.json, results.md{', videos/' if args.video else ''})")
    return published_exit_code("evaluate.py", out, where)
