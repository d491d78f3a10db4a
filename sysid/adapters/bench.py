"""Calibration adapters of the bench rigs: the report's gearmotor (``--robot motor``) and the AX-12 servo
(``--robot servo``) replayed against their logs.

Both rigs measure the output shaft. Their effects:

| effect | motor | servo | applied as |
|---|---|---|---|
| delay | x | x | the command shifted in time (as MuJoCo's actuator delay would; whole physics steps) |
| coulomb_friction, viscous_friction, armature | x | x | the shaft's frictionloss, damping, armature |
| backlash | x | x | a second hinge on the load, free within +-gap/2 of the driven one (spec edit) |
| deadband | x | | the driver outputs nothing below a duty threshold |
| torque_constant, back_emf_constant, supply_voltage | x | supply only | the motor formula's Kt, Ks, Vs |
| supply_sag | x | | the supply's internal resistance: d^2 Rs added to the formula's d^2 Ramp |
| pwm_decay | x | | the bridge coasts through a fraction of the off-time: the back-EMF term scaled by 1 - m (1 - d) |
| servo_gain | | x | the amplifier's gain (compliance slope) |
| sensor_gain (angle), sensor_bias (speed) | x | | on the predicted channel |
| sensor_bias (position) | | x | on the predicted channel, counts |
| load_friction | | x | the dcmotor's torque out scaled by 1 - k where its amplifier saturates, 1 + k within the slope |
| stribeck_friction | | x | the dcmotor's LuGre friction, its Coulomb part 0 (the frictionloss holds that) |
| asymmetric_friction | | x | the mean level a frictionloss, half the difference a constant torque (dcmotor cogging) |
| gearbox_efficiency | | x | the dcmotor's resistance the winding's over the efficiency, gains kept to the duty law |

The servo's friction forms follow Rhoban's BAM (Duclusaud et al. 2024, 'Extended friction models for the physics
simulation of servo actuators'). BAM's load-dependent friction, a friction budget that follows the torque the gearbox
carries, cannot run natively (MuJoCo's friction levels are constants): its native form above takes k of the torque
from a motor driving its load and adds k to one braking it, as a position servo does while saturated and within its
compliance slope (tests/test_servo_friction.py measures it against BAM's form run in Python per step: it leaves 10
to 25% of the effect on a loaded bench, an efficiency-like scale 70 to 77%).

A servo log without its goal (the AX-12A step file) gets the goal as a nuisance: its level at the log's start, and
for each move between plateaus of the position (and a move still under way at the log's end) a step of fitted time
and level (smooth: the step is spread over the physics step it falls in). A servo log's record may declare the load
it moved (``load_inertia``, kg m^2 about the horn), which its replay takes; the generator records the load friction
and the gearbox efficiency so, on a loaded bench (:data:`LOADED_INERTIA`).
"""

from __future__ import annotations

import hashlib
import itertools
import math
import warnings
from collections.abc import Sequence
from dataclasses import replace

import mujoco
import numpy as np
import pandas as pd

from envs.actuators.dcmotor import GAIN_KP, GAIN_VMAX
from envs.actuators.motor import MotorConstants
from envs.actuators.servo import GEARBOX_EFFICIENCY, add_constant_torque, add_stribeck_friction, scale_output_torque
from envs.bench.robot import JOINT, LOAD, MotorRig, ServoRig
from envs.common.effects import GROUP_DRIVE, Effect, Param, make
from sysid.logs import Log, LogError
from sysid.problem import Adapter, Segment, Setting

PLAY = "play"
SERVO_TOP_SPEED = "servo top speed: viscous friction / supply voltage"
# on the servo, a gearbox that passes a fraction e of the motor's torque moves a frictionless load as an inertia 1/e
# times the rig's (the motor's own included) does: below its nominal value the efficiency is an armature
SERVO_LAG = "lag: delay / armature / gearbox efficiency"
# the least of the servo's torque a setting leaves (a thousandth: the motor stalls against any load), and the least
# Stribeck velocity (a thousandth of the rig's resolved speed, a count per 16 ms sample, 0.32 rad/s): the loop looks
# past a range's end (sysid/select.py, what the data ask for over a range moved out by its span), where a load
# friction of 1 or an efficiency of 0 would leave the motor nothing and a Stribeck velocity of 0 divide by zero
LEAST_TORQUE_SCALE = 1e-3
LEAST_STRIBECK_VELOCITY = 3e-4  # rad/s
# a servo log's record may declare the load's inertia about the horn (kg m^2), which its replay then takes
LOAD_INERTIA = "load_inertia"
# the loaded bench the generator records the effects that need load torque on (the servo's load friction and gearbox
# efficiency; the unloaded rig's 1e-4 kg m^2 is a tenth of the motor's own inertia at the output, 9.7e-4): a 100 g
# mass at the end of a 30 cm bar on the horn, 0.1 x 0.3^2 = 0.009 kg m^2, and the 30 g bar's own 0.0009
LOADED_INERTIA = 0.01  # kg m^2


def add_backlash(gap: float, rotor_inertia: float):
    """Spec edit: the load gets a second hinge ``play``, limited to +-gap/2, on the driven shaft's axis; the driven
    joint keeps a rotor inertia of its own, so that the load is free within the gap."""

    def edit(spec: mujoco.MjSpec) -> None:
        load = spec.body("load")
        joint = load.add_joint(name=PLAY, type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
        joint.range = [-gap / 2, gap / 2]
        joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        spec.joint(JOINT).armature += rotor_inertia
        spec.add_sensor(name="play_angle", type=mujoco.mjtSensor.mjSENS_JOINTPOS, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                        objname=PLAY)  # fmt: skip
        spec.add_sensor(name="play_speed", type=mujoco.mjtSensor.mjSENS_JOINTVEL, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                        objname=PLAY)  # fmt: skip

    return edit


def shaft_edit(setting: Setting):
    """Spec edit: the shaft's Coulomb and viscous friction and rotor inertia, added to the nominal joint's."""

    def edit(spec: mujoco.MjSpec) -> None:
        joint = spec.joint(JOINT)
        joint.frictionloss += setting.get("coulomb_friction.torque", 0.0)
        joint.damping += setting.get("viscous_friction.damping", 0.0)
        joint.armature += setting.get("armature.inertia", 0.0)

    return edit


def add_disturbance(spec: mujoco.MjSpec) -> None:
    """Spec edit (synthetic data only): a torque on the load from outside the model."""
    a = spec.add_actuator(name="disturbance", target=JOINT, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE


class RigAdapter(Adapter):
    """What the two rigs share: the shaft's effects, backlash, the disturbance, initial states and observations."""

    rig_class: type
    rig_kwargs: dict = {}  # noqa: RUF012 (read-only per class)
    angle_channel: str

    def __init__(self, load_inertia: float | None = None) -> None:
        super().__init__()
        self.load_inertia = load_inertia
        rig = self.nominal_robot = self._rig()
        self._h = float(rig.model.opt.timestep)
        self._load_inertia = float(rig.model.body_inertia[rig.model.body("load").id, 2])
        self._dof = int(rig.model.joint(JOINT).dofadr[0])

    def _rig(self, edits=()):
        kwargs = dict(self.rig_kwargs)
        if self.load_inertia is not None:
            kwargs["load_inertia"] = self.load_inertia
        return self.rig_class(spec_edits=list(edits), **kwargs)

    @property
    def physics_dt(self) -> float:
        return self._h

    def shaft_effects(self, friction: float, damping: float, armature: float) -> list[Effect]:
        return [
            make("delay", seconds=(0.0, 0.0, 0.05, self._h)),
            make("coulomb_friction", torque=(0.0, 0.0, friction)),
            make("viscous_friction", damping=(0.0, 0.0, damping)),
            make("armature", inertia=(0.0, 0.0, armature)),
            make("backlash", gap=(0.0, 0.0, 0.2)),
        ]

    def out_of_catalog(self) -> list[Effect]:
        return [make("disturbance", torque=(0.0, 0.0, 0.5), frequency=(3.0, 0.5, 10.0))]

    def spec_edits(self, setting: Setting) -> list:
        return [
            shaft_edit(setting),
            *self.structural_edits(
                setting, lambda gap: add_backlash(gap, 0.01 * self._load_inertia), disturbance=add_disturbance
            ),
        ]

    def _shaft(self, model: mujoco.MjModel, sensordata: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Angle and speed of the load (driven shaft plus play)."""
        angle = sensordata[:, model.sensor("angle").adr[0]]
        speed = sensordata[:, model.sensor("speed").adr[0]]
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, "play_angle") >= 0:
            angle = angle + sensordata[:, model.sensor("play_angle").adr[0]]
            speed = speed + sensordata[:, model.sensor("play_speed").adr[0]]
        return angle, speed

    def disturbance_ctrl(self, model: mujoco.MjModel, ctrl: np.ndarray, segment: Segment, setting: Setting) -> None:
        a = setting.get("disturbance.torque", 0.0)
        if a > 0:
            f = setting.get("disturbance.frequency", 3.0)
            t = segment.t0 + np.arange(len(ctrl)) * self._h
            ctrl[:, model.actuator("disturbance").id] = a * np.sin(2 * math.pi * f * t)

    def set_load(self, model: mujoco.MjModel, data: mujoco.MjData, angle: float, speed: float | None) -> None:
        """Put the load (driven shaft plus play) at a measured angle and speed (None: keep the speed); the play
        keeps its state (carried over from the previous segment), the driven shaft takes the rest."""
        play_angle = play_speed = 0.0
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, PLAY) >= 0:
            play = model.joint(PLAY)
            play_angle = float(data.qpos[play.qposadr[0]])
            play_speed = float(data.qvel[play.dofadr[0]])
        j = model.joint(JOINT)
        data.qpos[j.qposadr[0]] = angle - play_angle
        if speed is not None:
            data.qvel[j.dofadr[0]] = speed - play_speed


class MotorAdapter(RigAdapter):
    """The report's DC gearmotor on the rig, replayed from its duty cycle; compared on shaft angle and speed."""

    name = "motor"
    channels = {"angle": "rad", "speed": "rad/s"}  # noqa: RUF012
    commands = ("duty",)
    context = {"velocity": "speed", "command": "duty"}  # noqa: RUF012
    rig_class = MotorRig

    def __init__(self, load_inertia: float | None = None) -> None:
        super().__init__(load_inertia)
        self.constants = MotorConstants()

    def effects(self) -> dict[str, Effect]:
        # ranges of the same order as the motor's own: stall 2.17 N m, back-EMF damping 0.073 N m s/rad
        # wide enough to take the report's model to another gearmotor of its kind (the RHex3 log's runs at half its
        # no-load speed)
        shaft = {e.name: e for e in self.shaft_effects(friction=0.4, damping=0.2, armature=0.01)}
        # the drive and the back-EMF brake both scale with the torque constant (controls), and the shaft has no
        # friction of its own: a torque constant s times the nominal moves the load as an inertia 1/s times it does,
        # so below nominal the two are one effect on these channels (tests/test_calibration.py,
        # test_the_motors_torque_constant_below_nominal_is_one_effect_with_a_rotor_inertia)
        shaft["armature"] = replace(shaft["armature"], alias=GROUP_DRIVE)
        shaft["delay"] = replace(shaft["delay"], alias="lag: delay")
        out = [
            *shaft.values(),
            make("deadband", duty=(0.0, 0.0, 0.2)),
            make("torque_constant", scale=(1.0, 0.3, 3.0)),
            make("back_emf_constant", scale=(1.0, 0.3, 3.0)),
            make("supply_voltage", scale=(1.0, 0.3, 1.5)),
            make("supply_sag", resistance=(0.0, 0.0, 10.0)),
            make("pwm_decay", coast=(0.0, 0.0, 1.0)),
            make("sensor_gain", target="angle", scale=(1.0, 0.8, 1.25)),
            make("sensor_bias", target="speed", offset=(0.0, -2.0, 2.0)),
            *self.out_of_catalog(),
        ]
        return {e.name: e for e in out}

    def excite(self, seconds: float, rng: np.random.Generator) -> pd.DataFrame:
        """PWM steps of random level and length (a fifth of them off), sampled every 10 ms as the real log is."""
        t = np.arange(0.0, seconds, 0.01)
        duty = np.zeros_like(t)
        start = 0.0
        while start < seconds:
            hold = rng.uniform(0.15, 0.6)
            level = 0.0 if rng.random() < 0.2 else rng.uniform(-1.0, 1.0)
            duty[(t >= start) & (t < start + hold)] = level
            start += hold
        return pd.DataFrame({"time": t, "duty": np.round(duty * 255) / 255, "angle": 0.0, "speed": 0.0})

    def synth_noise(self) -> dict[str, float]:
        return {"angle": 2e-3, "speed": 0.05}

    def initial_state(self, model, data, segment: Segment, setting: Setting, carried: bool = False) -> None:
        speed = segment.data["speed"][0] - setting.get("sensor_bias_speed.offset", 0.0)
        self.set_load(model, data, segment.data["angle"][0], speed)

    def initial_uncertainty(self, model, segment: Segment, setting: Setting) -> list[tuple[str, int, float]]:
        j = model.joint(JOINT)
        return [("qpos", int(j.qposadr[0]), segment.sigma["angle"]), ("qvel", int(j.dofadr[0]), segment.sigma["speed"])]

    def controls(self, model, segment: Segment, setting: Setting) -> np.ndarray:
        t = self.physics_times(segment)
        duty = segment.command_at("duty", t, setting.get("delay.seconds", 0.0))
        band = setting.get("deadband.duty", 0.0)
        if band > 0:
            duty = np.sign(duty) * np.maximum(np.abs(duty) - band, 0.0)
        duty = np.clip(duty, -1.0, 1.0)
        c = self.constants
        kt = c.torque_constant * setting.get("torque_constant.scale", 1.0)
        ks = c.speed_constant * setting.get("back_emf_constant.scale", 1.0)
        vs = c.supply_voltage * setting.get("supply_voltage.scale", 1.0)
        # a supply of internal resistance Rs drops by Rs d i: the motor sees d Vs - d^2 Rs i, an amplifier resistance
        r = c.motor_resistance + duty**2 * (c.amplifier_resistance + setting.get("supply_sag.resistance", 0.0))
        per_amp = c.efficiency * c.gear_ratio * kt
        ctrl = np.zeros((len(t), model.nu))
        ctrl[:, model.actuator(f"{JOINT}_drive").id] = per_amp * duty * vs / r
        # coasting through a fraction m of the off-time, the back-EMF brakes during 1 - m (1 - |d|) of the period
        coast = setting.get("pwm_decay.coast", 0.0)
        ctrl[:, model.actuator(f"{JOINT}_emf").id] = per_amp * ks / r * (1.0 - coast * (1.0 - np.abs(duty)))
        self.disturbance_ctrl(model, ctrl, segment, setting)
        return ctrl

    def observe(self, sensordata: np.ndarray, segment: Segment, setting: Setting) -> np.ndarray:
        angle, speed = self._shaft(self.model_for(setting), sensordata)
        start = segment.data["angle"][0]
        angle = start + (angle - start) * setting.get("sensor_gain_angle.scale", 1.0)
        return np.column_stack([angle, speed + setting.get("sensor_bias_speed.offset", 0.0)])


class ServoAdapter(RigAdapter):
    """The AX-12 on the rig, replayed from its goal (or from a fitted goal when the log lacks it); compared on the
    position it reports, in counts."""

    optional = ("goal",)  # logged, or fitted as a nuisance (Adapter.nuisance)

    name = "servo"
    channels = {"present_position": "count"}  # noqa: RUF012
    segment_seconds = 0.5  # a servo settles within a quarter second: shorter segments, more of them
    commands = ()
    rig_class = ServoRig

    def __init__(self, load_inertia: float | None = None) -> None:
        super().__init__(load_inertia)
        rig = self._rig()
        self.servo_constants = rig.servo.constants
        self._servo = rig.servo.actuator_name(JOINT)

    def effects(self) -> dict[str, Effect]:
        shaft = {e.name: e for e in self.shaft_effects(friction=0.3, damping=0.05, armature=0.005)}
        # on a position-only channel, viscous friction and the supply both set the servo's top speed
        shaft["viscous_friction"] = replace(shaft["viscous_friction"], alias=SERVO_TOP_SPEED)
        shaft["delay"] = replace(shaft["delay"], alias=SERVO_LAG)
        shaft["armature"] = replace(shaft["armature"], alias=SERVO_LAG)
        out = [
            *shaft.values(),
            make("servo_gain", scale=(1.0, 0.25, 4.0)),
            make("supply_voltage", scale=(1.0, 0.5, 1.5), alias=SERVO_TOP_SPEED),
            make("sensor_bias", target="position", offset=(0.0, -20.0, 20.0)),
            *self.friction_effects(),
            *self.out_of_catalog(),
        ]
        return {e.name: e for e in out}

    def friction_effects(self) -> list[Effect]:
        """The friction forms a Dynamixel needs beyond Coulomb and viscous ones, after Rhoban's BAM (Duclusaud et al.
        2024, 'Extended friction models for the physics simulation of servo actuators'), and the gearbox's
        efficiency. Ranges and their sources beside each."""
        out = [
            # BAM's load-dependent friction, its coefficient K_l of |tau_m - tau_e| bounded by BAM's own fit range,
            # [0, 0.5]; BAM fits 0.22 to the XL-320 (bam/params/xl320/m4.json), plastic-geared as the AX-12 is
            make("load_friction", coefficient=(0.0, 0.0, 0.5)),
            # BAM's Stribeck term: its static level bounded by BAM's fit range for friction levels, [0, 0.2] N m
            # (it fits 0.02 to the XL-320 and the MX-64); its Stribeck velocity from BAM's lower bound, 0.1 rad/s,
            # to above its fits to the XL-320 and MX-64 (2.0 and 1.5 rad/s), about half the AX-12's no-load speed at
            # 10 V (5.3 rad/s [ax12-manual]): 2.5 rad/s. BAM also fits the decay's exponent (1.3 to 1.8); MuJoCo's
            # LuGre fixes it at 2. Nominal 0.5 rad/s, a shape: with no static level it does nothing
            make("stribeck_friction", static=(0.0, 0.0, 0.2), velocity=(0.5, 0.1, 2.5)),
            # Coulomb friction by direction, a level against each: each level as the Coulomb friction's range. Two
            # levels rather than a level and an asymmetry factor: a factor on a friction that starts at zero has
            # no gradient there, and the loop, blind to it, keeps a Coulomb friction instead
            make("asymmetric_friction", positive=(0.0, 0.0, 0.3), negative=(0.0, 0.0, 0.3)),
            # the model's lumped efficiency, GEARBOX_EFFICIENCY (0.72, from the AX-12A's stall current), from a
            # lossless gearbox (1: the physical bound) down to 0.4 (assumed: 0.83 a stage over five spur stages, a
            # worn or cold train)
            make("gearbox_efficiency", efficiency=(GEARBOX_EFFICIENCY, 0.4, 1.0), alias=SERVO_LAG),
        ]
        loaded = {"record": {LOAD_INERTIA: LOADED_INERTIA}}  # load torque to show (sysid.synth.recording)
        return [replace(e, meta=loaded) if e.name in ("load_friction", "gearbox_efficiency") else e for e in out]

    def check_logs(self, logs: Sequence[Log]) -> None:
        """The model is an AX-12: a log of another servo (a Wizard export names its model) is calibrated as one,
        with a warning, since what differs (gearing, motor) is what the fit's effects would have to absorb. A load
        the log's record declares must be an inertia (positive, finite, kg m^2)."""
        for log in logs:
            load = log.meta.get(LOAD_INERTIA)
            if load is not None and not (isinstance(load, (int, float)) and math.isfinite(load) and load > 0):
                raise LogError(f"{log.path}: field '{LOAD_INERTIA}' of the log's record: {load!r} is not a load "
                               "inertia (kg m^2, positive)")  # fmt: skip
            model = log.meta.get("model")
            if model and not str(model).upper().replace("-", "").startswith("AX12"):
                warnings.warn(
                    f"{log.path}: the export is of an {model} servo; the model is an AX-12A (its gearing and motor "
                    "differ: the fitted effects absorb the difference)",
                    stacklevel=2,
                )

    # --- the goal: logged, or a nuisance -----------------------------------------------------------------------------
    def nuisance(self, logs: Sequence[Log]) -> dict[str, Param]:
        out = {}
        for source, log in enumerate(logs):  # the logs of a Problem, in its order (Segment.source)
            if "goal" not in log.df.columns:
                out.update(self.goal_plan(log, source))
        return out

    @staticmethod
    def plateaus(log: Log) -> list[tuple[int, int]]:
        """Runs of rows where the reported position holds still (under 2 counts per 16 ms) for at least 0.15 s."""
        t = log.time
        x = log.df["present_position"].to_numpy(dtype=float)
        still = np.abs(np.gradient(x, t)) < 2.0 / 0.016
        runs, start = [], None
        for i, s in enumerate(still):
            if s and start is None:
                start = i
            if (not s or i == len(x) - 1) and start is not None:
                end = i if not s else i + 1
                if t[end - 1] - t[start] >= 0.15:
                    runs.append((start, end))
                start = None
        return runs

    def goal_plan(self, log: Log, source: int = 0) -> dict[str, Param]:
        """An unlogged goal as nuisance parameters: its level at the log's start, and a step (time, level) for each
        move between plateaus of the reported position, and for a move still under way when the log ends. A level
        seen on a plateau may differ from it by the servo's steady error (+-40 counts); one never seen (the log
        starts or ends moving) gets a wide range. ``source``: the log's place in its problem's logs, which keys its
        parameters with its path (two logs may share a path)."""
        tag = _tag(source, log.path)
        t = log.time
        x = log.df["present_position"].to_numpy(dtype=float)
        runs = self.plateaus(log)
        wide = 300.0
        out: dict[str, Param] = {}
        if not runs:
            out[f"{tag}start.level"] = Param("level", "count", x[-1], x[-1] - wide, x[-1] + wide)
            return out
        first = float(np.median(x[runs[0][0] : runs[0][1]]))
        near = 40.0 if runs[0][0] == 0 else wide
        out[f"{tag}start.level"] = Param("level", "count", first, first - near, first + near)
        k = 0
        for (a0, a1), (b0, b1) in itertools.pairwise(runs):
            before, after = float(np.median(x[a0:a1])), float(np.median(x[b0:b1]))
            if abs(after - before) > 5:
                t_move = float(t[a1 - 1])
                out[f"{tag}{k}.time"] = Param("time", "s", t_move, t_move - 0.3, t_move + 0.05)
                out[f"{tag}{k}.level"] = Param("level", "count", after, after - 40, after + 40)
                k += 1
        last0, last1 = runs[-1]
        held = float(np.median(x[last0:last1]))
        if last1 < len(x) and abs(x[-1] - held) > 5:  # moving when the log ends
            t_move = float(t[last1 - 1])
            reach = max(wide, 2 * abs(x[-1] - held))
            out[f"{tag}{k}.time"] = Param("time", "s", t_move, t_move - 0.3, t_move + 0.05)
            out[f"{tag}{k}.level"] = Param("level", "count", x[-1], x[-1] - reach, x[-1] + reach)
        return out

    def goal(self, segment: Segment, setting: Setting, times: np.ndarray) -> np.ndarray:
        """The goal (counts) at physics times of a segment: the log's, or the fitted steps between plateaus; each
        fitted step is spread over the physics step it falls in, so that its time is a smooth parameter."""
        delay = setting.get("delay.seconds", 0.0)
        if "goal" in segment.data:
            return segment.command_at("goal", times, delay)
        tag = _tag(segment.source, segment.log)
        steps = sorted((setting[k], k) for k in setting if k.startswith(tag) and k.endswith(".time"))
        absolute = segment.t0 + times - delay
        level = float(setting[f"{tag}start.level"])
        goal = np.full(len(times), level)
        for t_step, key in steps:
            new = setting[key.replace(".time", ".level")]
            goal += np.clip((absolute - t_step) / self._h + 1.0, 0.0, 1.0) * (new - level)
            level = new
        return goal

    def segments(self, log: Log) -> list[Segment]:
        """Segments, each holding the load its log's record declares (None: the rig's own)."""
        out = super().segments(log)
        load = log.meta.get(LOAD_INERTIA)
        for seg in out:
            seg.cache[LOAD_INERTIA] = None if load is None else float(load)
        return out

    def segment_edits(self, segment: Segment, setting: Setting) -> tuple[tuple, list]:
        """The load a segment's log declares, as the rig sets its own (``BenchRig.configure``); none without."""
        load = segment.cache.get(LOAD_INERTIA)
        if load is None:
            return (), []

        def edit(spec: mujoco.MjSpec) -> None:
            spec.body(LOAD).inertia = [load] * 3

        return (load,), [edit]

    def initial_state(self, model, data, segment: Segment, setting: Setting, carried: bool = False) -> None:
        """The measured position; the speed (not logged) carried over, or from the first two samples."""
        start = segment.data["present_position"][0] - setting.get("sensor_bias_position.offset", 0.0)
        speed = None if carried else self._start_speed(segment)[0]
        self.set_load(model, data, self.servo_constants.angle(start), speed)

    def _start_speed(self, segment: Segment) -> tuple[float, float]:
        """The load's speed at a segment's start from the first two samples, and its standard deviation."""
        x, t = segment.data["present_position"], segment.data["time"]
        if len(x) < 2 or t[1] <= t[0]:
            return 0.0, 1.0
        rad = self.servo_constants.angle(1.0) - self.servo_constants.angle(0.0)  # rad per count
        dt = float(t[1] - t[0])
        sd = math.sqrt(2.0) * segment.sigma.get("present_position", 1.0) * rad / dt
        return float((x[1] - x[0]) * rad / dt), sd

    def initial_uncertainty(self, model, segment: Segment, setting: Setting) -> list[tuple[str, int, float]]:
        j = model.joint(JOINT)
        rad = abs(self.servo_constants.angle(1.0) - self.servo_constants.angle(0.0))
        return [
            ("qpos", int(j.qposadr[0]), segment.sigma["present_position"] * rad),
            ("qvel", int(j.dofadr[0]), self._start_speed(segment)[1]),
        ]

    def controls(self, model, segment: Segment, setting: Setting) -> np.ndarray:
        t = self.physics_times(segment)
        goal = np.clip(self.goal(segment, setting, t), 0, self.servo_constants.counts - 1)
        ctrl = np.zeros((len(t), model.nu))
        servo = model.actuator(self._servo).id
        ctrl[:, model.actuator_ctrladr[servo]] = model.actuator_gear[servo, 0] * self.servo_constants.angle(goal)
        self.disturbance_ctrl(model, ctrl, segment, setting)
        return ctrl

    def spec_edits(self, setting: Setting) -> list:
        gain = setting.get("servo_gain.scale", 1.0)
        supply = setting.get("supply_voltage.scale", 1.0)
        efficiency = setting.get("gearbox_efficiency.efficiency", GEARBOX_EFFICIENCY) / GEARBOX_EFFICIENCY
        load = setting.get("load_friction.coefficient", 0.0)
        saturated = max(efficiency * (1.0 - load), LEAST_TORQUE_SCALE)
        linear = max(efficiency * (1.0 + load), LEAST_TORQUE_SCALE)
        static = setting.get("stribeck_friction.static", 0.0)
        velocity = max(setting.get("stribeck_friction.velocity", 0.5), LEAST_STRIBECK_VELOCITY)
        positive = setting.get("asymmetric_friction.positive", 0.0)
        negative = setting.get("asymmetric_friction.negative", 0.0)

        def servo_edit(spec: mujoco.MjSpec) -> None:  # after the servo's own configuration (robot spec edits run last)
            a = spec.actuator(self._servo)
            a.gainprm[GAIN_KP] *= gain * supply
            a.gainprm[GAIN_VMAX] *= supply
            # the efficiency scales the torque out alike in every regime; the load-dependent friction takes it from
            # a motor that drives the load (saturated: accelerating it toward a far goal) and adds it to one that
            # brakes it (within the compliance slope: stopping it on the goal)
            scale_output_torque(a, saturated, linear)
            if self._bristles(setting):
                add_stribeck_friction(a, static, velocity)
            if positive or negative:  # their mean a frictionloss, half their difference a constant torque
                spec.joint(JOINT).frictionloss += 0.5 * (positive + negative)
                add_constant_torque(a, -0.5 * (positive - negative))

        return [*super().spec_edits(setting), servo_edit]

    @staticmethod
    def _bristles(setting: Setting) -> bool:
        """Whether a setting's model has the Stribeck friction's bristle state (an activation: a structural change)."""
        return setting.get("stribeck_friction.static", 0.0) > 0

    def structure(self, setting: Setting) -> tuple:
        """The structural effects of :class:`~sysid.problem.Adapter`, and the Stribeck friction's bristle state."""
        return (*super().structure(setting), self._bristles(setting))

    def excite(self, seconds: float, rng: np.random.Generator) -> pd.DataFrame:
        """Goal steps of random size and length, sampled every 12 to 20 ms (irregular, as the Wizard samples)."""
        t = np.cumsum(rng.uniform(0.012, 0.020, int(seconds / 0.012) + 10))
        t = t[t < seconds] - t[0]
        goal = np.full_like(t, 512.0)
        start = rng.uniform(0.2, 0.5)
        while start < seconds:
            hold = rng.uniform(0.4, 1.0)
            goal[t >= start] = float(rng.integers(250, 775))
            start += hold
        return pd.DataFrame({"time": t, "goal": goal, "present_position": 512.0})

    def synth_noise(self) -> dict[str, float]:
        return {"present_position": 0.3}

    def measure(self, channel: str, values: np.ndarray) -> np.ndarray:
        return np.rint(values)  # the servo reports whole counts

    def recorded_noise(self, noise: dict[str, float]) -> dict[str, float]:
        return {c: float(np.sqrt(s * s + 1.0 / 12.0)) for c, s in noise.items()}

    def observe(self, sensordata: np.ndarray, segment: Segment, setting: Setting) -> np.ndarray:
        angle, _ = self._shaft(self.model_for(setting), sensordata)
        # not rounded: the prediction stays smooth in the parameters; the reported counts' rounding is noise
        return (self.servo_constants.counts_of(angle) + setting.get("sensor_bias_position.offset", 0.0))[:, None]

    def noise(self, log: Log) -> dict[str, float]:
        recorded = log.meta.get("noise_sigma") or {}
        # the servo reports whole counts: quantisation noise of one count, sigma 1/sqrt(12)
        return {"present_position": float(recorded.get("present_position", 1.0 / math.sqrt(12)))}


def _tag(source: int, path: str) -> str:
    """The prefix of an unlogged goal's parameters: the log's place in its problem and a hash of its path (the place
    tells two logs with one path apart; the path keeps a training log's goal apart from a held-out one's)."""
    return f"goal_{source}_{hashlib.sha1(str(path).encode()).hexdigest()[:6]}_"


ADAPTERS = {"motor": MotorAdapter, "servo": ServoAdapter}
