"""The static validation of [bioloid-webots, V, Tables 4-5] on our Bioloid: set a posture, move one servo a count at a
time until the robot tips, report that servo value (the "equilibrium value"), beside the real robot's and the report's
Webots model's.

- **Postures**: Table 4's nine, all sixteen servos in counts, on the ground.
- **The servo moved**: N_1, the neck's pitch servo, in all nine. The report's text does not name it, but it
  names the head for experiment 3 ("in any position of the head the robot doesn't fall"), and N_1 is the one servo
  that moves the head's weight (N_2 and HEAD, 228 g, 13% of the robot) fore and aft without touching the support: the
  postures change the legs (experiments 1-6) and the head's roll (N_2, experiments 8-9), the moved servo probes how
  far the centre of mass may go. Mirrored setups (5 and 6) tipping the same way (261 and 274, both below 513) also
  fit a pitch servo, not a roll servo. The report does not give the direction either: both are run, and the one on
  the side of the real robot's value is compared (its sign is the one fact taken from the answer).
- **Protocol**: the robot is put down level on its lowest point (2 mm up), its servos holding the posture, and left
  3 s to settle into the attitude it rests in (a posture with legs spread fore and aft rests tilted on them, as the
  real robot "disposed in a stable position" would). "Fell during setup" (the report's X) if it finds no rest: its body
  still turning more than 1 deg over the last second of settling, or turned over (tilt past 90 deg); a threshold on
  the tilt itself would split steady rests a few degrees apart for no physical reason. Then N_1's goal moves one
  count every 0.1 s (slow against the servo: no inertia, as the seed wanted) until the robot tips: its body turns
  more than 5 deg within one count's 0.1 s, a free rotation about the edge of its support (assumed threshold: the
  seed gives none), or N_1 reaches 0 or 1023 ("did not fall", the report's circle). A tilt from the rest is no tip:
  where the robot rests on its head (experiments 1, 3, 7, 8, 9), moving N_1 pushes the body up on it smoothly, about
  0.1 deg per count. That reading is reported beside the tip, as "tilted 15 deg from rest".

Run: ``python -m benchmarks.bioloid_static`` (about half a minute).
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

from benchmarks.common import add_output_options, md_table, resolve_output
from envs.bioloid import constants
from envs.bioloid.robot import Bioloid
from envs.common.io import ToolParser

TABLE4 = {  # [bioloid-webots, Table 4]: servo -> counts in experiments 1..9
    "PELVIS": (513, 513, 205, 819, 513, 513, 513, 513, 513),
    "F_L_1": (513, 513, 0, 0, 513, 513, 513, 513, 513),
    "F_R_1": (513,) * 9,
    "F_L_2": (205, 819, 819, 819, 867, 513, 513, 513, 513),
    "F_R_2": (819, 205, 513, 513, 513, 166, 513, 513, 513),
    "F_L_3": (513,) * 9,
    "F_R_3": (513,) * 9,
    "B_L_1": (513,) * 9,
    "B_R_1": (513,) * 9,
    "B_L_2": (580, 444, 513, 513, 166, 513, 513, 513, 513),
    "B_R_2": (444, 580, 819, 819, 513, 867, 513, 513, 513),
    "B_L_3": (513,) * 9,
    "B_R_3": (513,) * 9,
    "N_1": (513,) * 9,
    "N_2": (513, 513, 513, 513, 513, 513, 513, 819, 205),
    "HEAD": (513,) * 9,
}
REAL = (571, 482, 479, 535, 261, 274, 478, 537, 542)  # [bioloid-webots, Table 5]
WEBOTS = (531, "fell", 0, "fell", 363, 375, 466, 527, 531)  # [bioloid-webots, Table 5] (X: fell during setup)
MOVED = "N_1"
SETTLE = 3.0  # s
DWELL = 0.1  # s per count
TIP_STEP = np.radians(5.0)  # a fall: the body turns this much within one count's dwell (50 deg/s; a quasi-static
# push on the head turns it about 0.1 deg per count, 1 deg/s, so a free rotation about the support is 50 times that)
PUSHED = np.radians(15.0)  # a second reading: tilt this far from the rest, fall or not
REST_WINDOW = 1.0  # s: the last part of settling, over which a body at rest turns less than REST_TURN
REST_TURN = np.radians(1.0)


def posture(experiment: int) -> np.ndarray:
    return np.array([TABLE4[s][experiment] for s in constants.SERVOS], dtype=np.float64)


def lowest_point(robot: Bioloid, counts: np.ndarray) -> float:
    """Height (m) of the lowest point of the collision shapes, level, the body's origin at 0, in posture ``counts``."""
    m = robot.model
    d = mujoco.MjData(m)
    d.qpos[robot._servo_qpos] = (counts - constants.CENTER) * constants.RAD_PER_COUNT
    d.qpos[:7] = [0, 0, 0, 1, 0, 0, 0]
    mujoco.mj_kinematics(m, d)
    lowest = 0.0
    for g in range(m.ngeom):
        if m.geom_bodyid[g] == 0:
            continue
        rot = d.geom_xmat[g].reshape(3, 3)
        size = m.geom_size[g]
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            half = np.abs(rot[2]) @ size
        elif m.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE:
            half = abs(rot[2, 2]) * size[1] + size[0]
        else:
            half = size[0]
        lowest = min(lowest, d.geom_xpos[g, 2] - half)
    return lowest


def tilt(quaternion: np.ndarray) -> np.ndarray:
    """Angle of the body's z axis from the world's z, rad."""
    q = quaternion
    return np.arccos(np.clip(1.0 - 2.0 * (q[:, 1] ** 2 + q[:, 2] ** 2), -1.0, 1.0))


def body_axes(quaternion: np.ndarray) -> np.ndarray:
    """The body's z axis in the world, (n, 3)."""
    w, x, y, z = quaternion.T
    return np.column_stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])


def run(experiments: list[int]) -> list[dict]:
    n = 2 * len(experiments)
    robot = Bioloid(imu_noise=None, num_sims=n, batched=True, nthread=1)
    rngs = [np.random.default_rng(0) for _ in range(n)]
    for k, e in enumerate(experiments):
        counts = posture(e)
        height = -lowest_point(robot, counts) + 0.002
        robot.reset(np.array([2 * k, 2 * k + 1]), rngs[:2], 0.0, {"counts": counts, "height": height})
    start = body_axes(robot.read(rngs, stepped=False)["quaternion"])
    goal = robot.goal.copy()
    settle_steps, window_steps = round(SETTLE / robot.control_dt), round(REST_WINDOW / robot.control_dt)
    for k in range(settle_steps):
        robot.command(goal)
        robot.step()
        if k == settle_steps - window_steps - 1:
            before = body_axes(robot.read(rngs)["quaternion"])
    settled = body_axes(robot.read(rngs)["quaternion"])
    turning = np.arccos(np.clip((before * settled).sum(axis=1), -1, 1)) > REST_TURN
    turned_over = (start * settled).sum(axis=1) < 0.0
    setup_fall = turning | turned_over
    direction = np.tile([1.0, -1.0], len(experiments))
    column = constants.SERVO_INDEX[MOVED]
    tipped_at, pushed_at = np.full(n, np.nan), np.full(n, np.nan)
    active = ~setup_fall
    per_count = round(DWELL / robot.control_dt)
    last = settled
    while active.any():
        goal[active, column] += direction[active]
        at_end = (goal[:, column] <= 0) | (goal[:, column] >= constants.COUNTS - 1)
        for _ in range(per_count):
            robot.command(goal)
            robot.step()
        axes = body_axes(robot.read(rngs)["quaternion"])
        moved = np.arccos(np.clip((axes * settled).sum(axis=1), -1, 1))
        step = np.arccos(np.clip((axes * last).sum(axis=1), -1, 1))
        last = axes
        pushed = active & (moved > PUSHED) & np.isnan(pushed_at)
        pushed_at[pushed] = goal[pushed, column]
        tipped = active & (step > TIP_STEP)
        tipped_at[tipped] = goal[tipped, column]
        active &= ~tipped & ~at_end
    rows = []
    for k, e in enumerate(experiments):
        up, down = 2 * k, 2 * k + 1
        real = REAL[e]
        toward = up if real >= TABLE4[MOVED][e] else down
        value = "fell" if setup_fall[toward] else (tipped_at[toward] if np.isfinite(tipped_at[toward]) else "no fall")
        rows.append({
            "experiment": e + 1,
            "real": real,
            "webots": WEBOTS[e],
            "moved": MOVED,
            "direction": "up" if toward == up else "down",
            "ours": value if isinstance(value, str) else int(value),
            "ours_up": _value(setup_fall[up], tipped_at[up]),
            "ours_down": _value(setup_fall[down], tipped_at[down]),
            "pushed_15_up": _value(setup_fall[up], pushed_at[up]),
            "pushed_15_down": _value(setup_fall[down], pushed_at[down]),
            "rest_tilt_deg": float(np.degrees(np.arccos(np.clip(start[toward] @ settled[toward], -1, 1)))),
            "settled_tilt_deg": float(np.degrees(tilt(robot.read(rngs)["quaternion"])[toward])),
        })  # fmt: skip
    return rows


def _value(fell: bool, at: float) -> str | int:
    if fell:
        return "fell"
    return int(at) if np.isfinite(at) else "no fall"


CONFIGURATIONS: dict[str, list[str]] = {"bioloid_static": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "bioloid_static", CONFIGURATIONS)
    started = time.perf_counter()
    rows = run(list(range(9)))
    wall = time.perf_counter() - started
    diffs = [abs(r["ours"] - r["real"]) for r in rows if isinstance(r["ours"], int)]
    webots = [abs(w - r) for w, r in zip(WEBOTS, REAL, strict=True) if isinstance(w, int)]
    table = md_table(
        ["experiment", "real", "seed's Webots", "ours (toward real)", "ours up", "ours down", "|ours - real|",
         "ours: rest tilt from level, deg", "ours: tilted 15 deg from rest, up / down"],
        [[r["experiment"], r["real"], r["webots"], r["ours"], r["ours_up"], r["ours_down"],
          abs(r["ours"] - r["real"]) if isinstance(r["ours"], int) else "-", round(r["rest_tilt_deg"], 1),
          f"{r['pushed_15_up']} / {r['pushed_15_down']}"] for r in rows],
    )  # fmt: skip
    md = (
        "# Static validation [bioloid-webots, Tables 4-5] on the MuJoCo Bioloid\n\n"
        f"Servo moved: {MOVED} (neck pitch), one count per {DWELL:g} s after {SETTLE:g} s of settling; tipped = the "
        f"body turns more than {np.degrees(TIP_STEP):.0f} deg within one count's {DWELL:g} s (a fall, not a push); "
        f"fell during setup = no rest found (still turning over the last {REST_WINDOW:g} s of settling, or turned "
        f"over). The last column is the earlier reading: where the tilt first departs "
        f"{np.degrees(PUSHED):.0f} deg from the rest, fall or quasi-static push. Values in counts.\n\n"
        + table
        + f"\nOurs: {len(diffs)} of 9 comparable, mean |diff| {np.mean(diffs) if diffs else float('nan'):.0f} counts, "
        f"max {max(diffs) if diffs else float('nan')}; the report's Webots: {len(webots)} of 9, mean "
        f"{np.mean(webots):.0f}, max {max(webots)} (it fell twice during setup).\n"
        f"\nWall time {wall:.0f} s.\n"
    )
    output.save({"rows": rows, "moved": MOVED, "dwell_s": DWELL, "tip_step_deg": float(np.degrees(TIP_STEP)),
                            "wall_seconds": wall}, md)  # fmt: skip


if __name__ == "__main__":
    main()
