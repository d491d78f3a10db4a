"""Calibration of the Bioloid quadruped against its servo logs (``calibrate.py --robot bioloid``), and the calibrated
model (``gym.make("skitter/BioloidWalk-v2", calibration=PATH)``).

**Replay.** A Bioloid log holds, per servo, the goal position it was sent and the position it reports (counts), and
optionally the servos' supply (``vbatt``). The goals are replayed natively: every servo is the shared AX-12 model
(envs/actuators/servo.py), whose position controller (compliance slope, duty bound, motor and supply) runs inside
MuJoCo's dcmotor at every physics step, so a whole rollout is one ``mujoco.rollout`` call with no Python per step.
A row of the robot's telemetry holds the goal of the control step that *ended* at its time (envs/common/env.py
records after stepping), so the replay takes a step's goals from the row after its start; goals are held between
samples. A log's supply sets each segment's servo gains (the amplifier's duty times the supply; a segment's median
voltage, to 0.05 V); without ``vbatt`` the nominal 10 V is assumed.

Multiple shooting over one-second segments: each starts from the 16 measured servo angles; their speeds (not logged
by the report's robot) and the body (pose, motion, contacts) are carried over from the previous segment, as the
VelociRoACH's and the xJüs's are, with the body lifted if a leg turned to its measured angle would start inside the
ground. A log's first segment starts the body level at rest on its lowest sole and is only replayed to carry its end
over (``burn_in``). The replay floor is measured on the model's own twin of the log (sysid/problem.py).

**Channels** compared: the 16 reported positions (counts). The AX-12's "present load" is not compared: it reports
the amplifier's duty, not a torque (ROBOTIS e-manual), and it is the coarsest of its readings.

**Effects** (envs/bioloid/effects.py): delay of the goals; the servos' gain (compliance slope) and supply; per side (the
six servos of a side's two legs) Coulomb and viscous friction at the joints; the servos' rotor inertia; backlash between
each servo's horn and the bracket it drives (a hinge of limited play, a structural spec edit); the crutches' friction
and contact; the body's (BODY: the CM-5 and battery, Table 3) mass and centre of mass; an offset on each side's reported
positions. Not offered: the compliance margin (a deadband the native servo cannot run, envs/actuators/servo.py; on
positions it aliases Coulomb friction), motor constants apart from the supply (the servo model's torque and speed both
scale with it: ``supply_voltage`` is that group), leg or spine stiffness (the robot's brackets are rigid).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np
import pandas as pd

from envs.actuators.dcmotor import GAIN_KP, GAIN_VMAX
from envs.bioloid import constants
from envs.bioloid.effects import SIDE_SERVOS, add_backlash, bioloid_effects, effects_edit
from envs.common import edits
from envs.common.effects import Effect
from sysid.logs import Log, LogError
from sysid.problem import Adapter, Segment, Setting

SUPPLY_STEP = 0.05  # V: segments whose median supply rounds alike share a model
NOMINAL_SUPPLY = constants.BATTERY_VOLTAGE


def supply_edit(volts: float):
    """Spec edit: the servos' gains at a logged supply of ``volts`` instead of the nominal 10 V."""

    def edit(spec: mujoco.MjSpec) -> None:
        ratio = volts / NOMINAL_SUPPLY
        for servo in constants.SERVOS:
            a = spec.actuator(f"{servo}_servo")
            a.gainprm[GAIN_KP] *= ratio
            a.gainprm[GAIN_VMAX] *= ratio

    return edit


def add_bump(height: float):
    """Spec edit (synthetic data only): bumps across the robot's path every 0.14 m, three each way from the middle
    of its feet at the start (x = -0.02 m; the feet stand from -0.11 to 0.07 m), so that a step either way meets
    one: the synthetic excitation walks the robot no more than 0.2 m."""
    return edits.add_bump(height, x=0.14, width=2.0, count=3, centre=-0.02)


# Spec edit (synthetic data only): a rolling torque on the body from outside the model (a tether, a cable); up to
# 3 N m, since the servos' stiff loops hide a smaller one from their positions (at 0.5 N m the nominal model's error
# on synthetic logs stays under 1)
add_disturbance = edits.add_site_disturbance("imu", axis=0)


def _side(servo: str) -> str | None:
    for side, servos in SIDE_SERVOS.items():
        if servo in servos:
            return side
    return None


class BioloidAdapter(Adapter):
    """The Bioloid replayed from its servos' logged goals through the AX-12 model."""

    optional = ("vbatt",)  # the servos' supply, where logged

    name = "bioloid"
    channels = {f"present_position_{s}": "count" for s in constants.SERVOS}  # noqa: RUF012
    commands = tuple(f"goal_{s}" for s in constants.SERVOS)
    segment_seconds = 1.0
    context = {
        key: {f"present_position_{s}": f"{column}_{s}" for s in constants.SERVOS}
        for key, column in (("velocity", "speed"), ("command", "goal"), ("load", "load"))
    } | {"supply": "vbatt"}
    replay_floor = True  # the body's state is not logged and its contacts make replay sensitive to it
    burn_in = True  # a log's first segment guesses the body's state: replayed, carried over, not counted
    fd_step = 0.02
    rough_cost = True
    chain_search = (1, 2, 1)
    stepwise = True  # its fits cost seconds, not minutes: each candidate fitted with the kept effects (sysid/select.py)
    sample_lag = 1  # telemetry reads the sensors of its control step's last physics step (as the xJüs's)

    def acts_on(self, effect: Effect, channel: str) -> bool:
        """A side's effect acts on that side's leg servos (``left``: ``present_position_F_L_1``)."""
        side = next((s for s in SIDE_SERVOS if effect.target == s or effect.target.endswith("_" + s)), None)
        if side is None:
            return super().acts_on(effect, channel)
        return _side(channel.removeprefix("present_position_")) == side

    def __init__(self) -> None:
        super().__init__()
        from envs.bioloid.robot import Bioloid

        self._robot_class = Bioloid
        robot = self.nominal_robot = self._make_robot(())
        m = robot.model
        self._h = float(m.opt.timestep)
        self._servo = robot.servo.constants
        self._stand = robot.stand_height
        self._ctrl = {s: int(m.actuator_ctrladr[m.actuator(f"{s}_servo").id]) for s in constants.SERVOS}
        self._gear = {s: float(m.actuator_gear[m.actuator(f"{s}_servo").id, 0]) for s in constants.SERVOS}
        self._pos = np.array([int(m.sensor(f"{s}_pos").adr[0]) for s in constants.SERVOS])
        self._ready = robot.ready_counts.copy()
        self._mode, self._control_dt = robot.mode, robot.control_dt

    def _make_robot(self, edits):
        return self._robot_class(imu_noise=None, spec_edits=list(edits))

    @property
    def physics_dt(self) -> float:
        return self._h

    def effects(self) -> dict[str, Effect]:
        return bioloid_effects(self._h)

    # --- logs -------------------------------------------------------------------------------------------------------
    def check_logs(self, logs: Sequence[Log]) -> None:
        for log in logs:
            for column in (*self.commands, *self.channels):
                x = log.df[column].to_numpy(dtype=float)
                bad = np.flatnonzero(~((x >= 0) & (x <= self._servo.counts - 1)))
                if len(bad):
                    raise LogError(f"{log.path}: row {int(bad[0])}, column {column!r}: {x[bad[0]]!r} is not a servo "
                                   f"position in counts (0..{self._servo.counts - 1})")  # fmt: skip
            if "vbatt" in log.df.columns:
                v = log.df["vbatt"].to_numpy(dtype=float)
                bad = np.flatnonzero(~((v > 3.0) & (v < 20.0)))
                if len(bad):
                    raise LogError(f"{log.path}: row {int(bad[0])}, column 'vbatt': {v[bad[0]]!r} is not a servo "
                                   "supply voltage (V)")  # fmt: skip

    def segments(self, log: Log) -> list[Segment]:
        """Segments with the goals that act from each sample on: a telemetry row holds the goals of the control
        step that ended at its time, so what acts from row k on is row k + 1's (the last row's is held)."""
        out = super().segments(log)
        self.attach(log, out, {f"acting_{s}": self.acting(log.df[f"goal_{s}"].to_numpy(dtype=float))
                               for s in constants.SERVOS})  # fmt: skip
        return out

    # --- replay -----------------------------------------------------------------------------------------------------
    def spec_edits(self, setting: Setting) -> list:
        return [effects_edit(setting), *self.structural_edits(setting, add_backlash, add_bump, add_disturbance)]

    def segment_edits(self, segment: Segment, setting: Setting) -> tuple[tuple, list]:
        """The servos' gains at the segment's logged supply (its median, to 0.05 V); none without ``vbatt``."""
        if "vbatt" not in segment.data:
            return (), []
        volts = round(float(np.median(segment.data["vbatt"])) / SUPPLY_STEP) * SUPPLY_STEP
        if abs(volts - NOMINAL_SUPPLY) < 1e-9:
            return (), []
        return (volts,), [supply_edit(volts)]

    def _addresses(self, model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray, int]:
        """The servos' qpos and dof addresses and the root's qpos address in ``model`` (an effect may add joints)."""
        joints = [model.joint(s) for s in constants.SERVOS]
        return (np.array([int(j.qposadr[0]) for j in joints]), np.array([int(j.dofadr[0]) for j in joints]),
                int(model.joint(constants.ROOT_JOINT).qposadr[0]))  # fmt: skip

    def _measured_angles(self, segment: Segment, setting: Setting) -> np.ndarray:
        counts = np.array([float(segment.data[f"present_position_{s}"][0]) for s in constants.SERVOS])
        bias = np.array([setting.get(f"sensor_bias_position_{side}.offset", 0.0) if side else 0.0
                         for side in map(_side, constants.SERVOS)])  # fmt: skip
        return self._servo.angle(counts - bias)

    def initial_state(self, model, data, segment: Segment, setting: Setting, carried: bool = False) -> None:
        """The measured servo angles; their speeds and the body carried over, or, fresh, at rest with the body level
        on its lowest sole."""
        qpos, _, root = self._addresses(model)
        angles = self._measured_angles(segment, setting)
        if not carried:
            data.qpos[:] = model.qpos0
            data.qvel[:] = 0.0
            data.qpos[qpos] = angles
            mujoco.mj_kinematics(model, data)
            lowest = min(data.site(constants.SOLE_SITE[leg]).xpos[2] for leg in constants.LEGS)
            data.qpos[root : root + 7] = [0.0, 0.0, float(0.2 - lowest) + 1e-4, 1.0, 0.0, 0.0, 0.0]
            return
        before = edits.deepest_contact(model, data)
        data.qpos[qpos] = angles
        after = edits.deepest_contact(model, data)
        if after < min(before, 0.0):
            data.qpos[root + 2] += min(before, 0.0) - after

    def controls(self, model, segment: Segment, setting: Setting) -> np.ndarray:
        t = self.physics_times(segment)
        delay = setting.get("delay.seconds", 0.0)
        ctrl = np.zeros((len(t), model.nu))
        top = self._servo.counts - 1
        for s in constants.SERVOS:
            goal = np.clip(segment.command_at(f"acting_{s}", t, delay), 0.0, top)
            ctrl[:, self._ctrl[s]] = self._gear[s] * self._servo.angle(goal)
        if setting.get("disturbance.torque", 0.0) > 0:
            f = setting.get("disturbance.frequency", 3.0)
            ctrl[:, model.actuator("disturbance").id] = setting["disturbance.torque"] * np.sin(
                2 * math.pi * f * (segment.t0 + t)
            )
        return ctrl

    def observe(self, sensordata: np.ndarray, segment: Segment, setting: Setting) -> np.ndarray:
        counts = self._servo.counts_of(sensordata[:, self._pos])
        for i, side in enumerate(map(_side, constants.SERVOS)):
            if side:
                counts[:, i] += setting.get(f"sensor_bias_position_{side}.offset", 0.0)
        return counts

    # --- synthetic logs ---------------------------------------------------------------------------------------------
    def excite(self, seconds: float, rng: np.random.Generator) -> pd.DataFrame:
        """Goals at the robot's 50 Hz: the report's IK gaits (trot, walk, pace; 0.5 to 2.5 Hz; each side's stride
        drawn in 0.3 to 1, so that it turns) for 1.5 to 3 s each, now and then a pause in a posture of its own,
        while the pelvis, neck and head servos wander slowly (they carry no leg, and a gait never moves them); the
        supply at 10 V sagging slowly. The first row is the ready posture, as the robot resets."""
        from agents.bioloid.ik import IKGait
        from envs.common.task import ObservationLayout

        dt, mode = self._control_dt, self._mode
        steps = round(seconds / dt)
        goals = np.tile(self._ready, (steps + 1, 1))
        k = 1
        while k <= steps:
            span = int(rng.uniform(1.5, 3.0) / dt)
            stop = min(steps + 1, k + span)
            local = np.arange(stop - k) * dt
            if rng.random() < 0.2:  # a pause: hips and knees moved to a posture of their own, held
                posture = self._ready + rng.uniform(-40.0, 40.0, 16)
                goals[k:stop] = posture
            else:
                gait = IKGait(ObservationLayout({}), mode, dt, str(rng.choice(["trot", "walk", "pace"])),
                              float(rng.uniform(0.5, 2.5)), steer=False)  # fmt: skip
                strides = np.repeat(rng.uniform(0.3, 1.0, 2)[None, :], len(local), axis=0)[:, [0, 1, 0, 1]]
                strides = strides * gait.lead_in(local)[:, None]
                goals[k:stop] = gait.counts(local, strides)[0]
            k = stop
        wander = {"PELVIS": 25.0, "N_1": 60.0, "N_2": 60.0, "HEAD": 60.0}  # counts: slow random walks, bounded
        for servo, reach in wander.items():
            i = constants.SERVO_INDEX[servo]
            walk = np.cumsum(rng.normal(0.0, reach * 0.05, steps + 1))
            walk = reach * np.tanh(walk / reach)
            walk[0] = 0.0
            goals[:, i] = self._ready[i] + walk
        goals = np.clip(np.rint(goals), constants.RANGE_LOW, constants.RANGE_HIGH)
        t = np.arange(steps + 1) * dt
        table = {"time": t, **{f"goal_{s}": goals[:, i] for i, s in enumerate(constants.SERVOS)},
                 "vbatt": 10.0 - 0.3 * t / max(seconds, 1e-9)}  # fmt: skip
        for i, s in enumerate(constants.SERVOS):  # the start the replay begins from: the ready posture
            table[f"present_position_{s}"] = float(self._ready[i])
        return pd.DataFrame(table).iloc[:steps]  # samples before ``seconds``: each in a segment

    def synth_noise(self) -> dict[str, float]:
        # the AX-12's potentiometer reading: noise of a third of a count before the servo rounds it (as the bench
        # rig's, sysid/adapters/bench.py)
        return {c: 0.3 for c in self.channels}

    def measure(self, channel: str, values: np.ndarray) -> np.ndarray:
        return np.rint(values)  # the servo reports whole counts

    def recorded_noise(self, noise: dict[str, float]) -> dict[str, float]:
        return {c: float(np.sqrt(s * s + 1.0 / 12.0)) for c, s in noise.items()}


ADAPTERS = {"bioloid": BioloidAdapter}
