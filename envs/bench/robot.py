"""One-joint bench rigs: an actuator model driving a load, on the robot contract.

The rig (``assets/bench/rig.xml``) is an output shaft turning a load about a vertical axis; its load inertia and the
shaft's Coulomb friction and viscous damping are constructor arguments and named parameters. :class:`MotorRig`
drives it with the xJüs report's gearmotor (envs/actuators/motor.py), :class:`ServoRig` with the AX-12 servo
(envs/actuators/servo.py). They are the actuators' test benches and, for calibration, the model of a bench log.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import ClassVar

import mujoco
import numpy as np

import assets
from envs.actuators.motor import Motor, MotorConstants
from envs.actuators.servo import Servo, ServoConstants
from envs.common.parameters import FieldRef, Parameter, ParameterMap, SpecEdit
from envs.common.robot import ActionMode, Facts, PlotGroup, Robot, check_number
from envs.common.telemetry import ChannelLimit

JOINT = "output"
LOAD = "load"
POSE_CHANNELS = {**{f"pos_{a}": "m" for a in "xyz"}, **{f"quat_{a}": "1" for a in "wxyz"}}


class BenchRig(Robot):
    """Base of the rigs: the load, its parameters, reset and the readings every rig shares.

    Args:
        action_mode: the rig's one action mode.
        control_freq: control steps per second.
        load_inertia: inertia of the load about the shaft, kg m^2.
        friction: Coulomb friction of the shaft, N m.
        damping: viscous damping of the shaft, N m s/rad.
        spec_edits, num_sims, nthread, batched: as for every robot.
    """

    root_body = LOAD
    actuator_channels: ClassVar[dict[str, str]] = {}

    def __init__(
        self,
        action_mode: str,
        control_freq: float | None = None,
        load_inertia: float = 1e-3,
        friction: float = 0.0,
        damping: float = 0.0,
        spec_edits: Sequence[SpecEdit] = (),
        num_sims: int | None = None,
        nthread: int | None = None,
        batched: bool | None = None,
    ):
        self.load_inertia = check_number("load_inertia", load_inertia, 0, strict=True)
        self.friction = check_number("friction", friction, 0)
        self.damping = check_number("damping", damping, 0)
        super().__init__(action_mode, control_freq, spec_edits, num_sims, nthread, batched)

    @classmethod
    def xml_path(cls) -> Path:
        return assets.path("bench", "rig.xml")

    def configure(self, spec: mujoco.MjSpec) -> None:
        body = spec.body(LOAD)
        body.inertia = [self.load_inertia] * 3
        joint = spec.joint(JOINT)
        joint.frictionloss = self.friction
        joint.damping = [self.damping, 0.0, 0.0]
        self.configure_actuator(spec)

    def configure_actuator(self, spec: mujoco.MjSpec) -> None:
        raise NotImplementedError

    def setup(self) -> None:
        m = self.model
        self._i_angle, self._i_speed = self.sensors["angle"].start, self.sensors["speed"].start
        self._i_pos, self._i_quat = self.sensors["load_pos"], self.sensors["load_quat"]
        self.command_now = np.zeros((self.num_sims, self.mode.size))
        self._mass = float(m.body_mass[m.body(LOAD).id])

    def build_parameters(self, model: mujoco.MjModel) -> ParameterMap:
        load = model.body(LOAD).id
        dof = model.joint(JOINT).dofadr[0]
        p = ParameterMap()
        p.add(Parameter("load_inertia", "kg m^2", self.load_inertia, 1e-7, 10.0, "inertia of the load about the shaft",
                        (FieldRef("body_inertia", (load, 2)),)))  # fmt: skip
        p.add(Parameter("friction", "N m", self.friction, 0.0, 5.0, "Coulomb friction of the shaft",
                        (FieldRef("dof_frictionloss", (dof,)),)))  # fmt: skip
        p.add(Parameter("damping", "N m s/rad", self.damping, 0.0, 5.0, "viscous damping of the shaft",
                        (FieldRef("dof_damping", (dof,)),)))  # fmt: skip
        return p

    @property
    def facts(self) -> Facts:
        return Facts(mass=self._mass, length=0.1, extra={"load_inertia": self.load_inertia, "friction": self.friction})

    @property
    def sense_structure(self) -> dict[str, int]:
        return {"angle": 1, "speed": 1}

    @property
    def telemetry_channels(self) -> dict[str, str]:
        return {"time": "s", **self.actuator_channels, **POSE_CHANNELS, "power": "W"}

    @property
    def plot_groups(self) -> tuple[PlotGroup, ...]:
        return (PlotGroup("shaft angle", "rad", ("angle",)), PlotGroup("shaft speed", "rad/s", ("speed",)))

    def reset(
        self, ids: np.ndarray, rngs: Sequence[np.random.Generator], noise: float = 0.0, options: Mapping | None = None
    ) -> None:
        """The shaft at rest at ``options["angle"]`` (rad, default 0), perturbed by U(-noise, noise)."""
        m = self.model
        qpos = np.zeros((len(ids), m.nq))
        for j, rng in enumerate(rngs):
            qpos[j, 0] = float((options or {}).get("angle", 0.0)) + rng.uniform(-noise, noise)
        self.command_now[ids] = self.rest_command(qpos[:, 0])
        self.sim.reset(ids, {"qpos": qpos, "qvel": np.zeros((len(ids), m.nv)), "act": np.zeros((len(ids), m.na))})
        self.command(self.command_now)

    def rest_command(self, angle: np.ndarray) -> np.ndarray:
        """The command that holds the shaft where it is."""
        return np.zeros((len(angle), self.mode.size))

    def read(self, rngs: Sequence[np.random.Generator], stepped: bool | np.ndarray = True) -> dict[str, np.ndarray]:
        sd = self.sim.sensordata
        power = np.where(stepped, self.substep_power(), 0.0) if stepped is not True else self.substep_power()
        angle, speed = sd[:, self._i_angle], sd[:, self._i_speed]
        pos, quat = sd[:, self._i_pos], sd[:, self._i_quat]
        time = self.sim.time
        return {
            "time": time,
            "position": pos,
            "quaternion": quat,
            "velocity": np.zeros_like(pos),
            "power": power,
            "senses": np.column_stack([angle, speed]),
        }

    def telemetry(self, readings: dict[str, np.ndarray], sensordata: np.ndarray | None = None) -> np.ndarray:
        channels = self.actuator_readings(self.sim.sensordata if sensordata is None else sensordata)
        return np.column_stack(
            [readings["time"], *channels, readings["position"], readings["quaternion"], readings["power"]]
        )

    def substep_power(self) -> np.ndarray:
        raise NotImplementedError

    def actuator_readings(self, sensordata: np.ndarray) -> list[np.ndarray]:
        raise NotImplementedError


class MotorRig(BenchRig):
    """The xJüs report's DC gearmotor [xjus-report, Table 1] on the rig, commanded by duty cycle, held per control step.

    Args:
        constants: the motor's constants (default: the report's Table 1).
        armature: rotor inertia reflected to the output, kg m^2 (the report gives none: 0).
        (the rest as :class:`BenchRig`; control at 100 Hz by default)
    """

    name = "motor"
    action_modes: ClassVar[dict[str, ActionMode]] = {
        "duty": ActionMode("duty", ("duty",), ("1",), (-1.0,), (1.0,), 100.0, "the motor's duty factor d"),
    }
    actuator_channels: ClassVar[dict[str, str]] = {
        "duty": "1",
        "angle": "rad",
        "speed": "rad/s",
        "torque": "N m",
        "current": "A",
    }

    def __init__(
        self,
        control_freq: float | None = None,
        load_inertia: float = 1e-3,
        friction: float = 0.0,
        damping: float = 0.0,
        constants: MotorConstants | None = None,
        armature: float = 0.0,
        spec_edits: Sequence[SpecEdit] = (),
        num_sims: int | None = None,
        nthread: int | None = None,
        batched: bool | None = None,
    ):
        self.motor = Motor([JOINT], constants, check_number("armature", armature, 0))
        super().__init__("duty", control_freq, load_inertia, friction, damping, spec_edits, num_sims, nthread, batched)

    def configure_actuator(self, spec: mujoco.MjSpec) -> None:
        self.motor.configure(spec)

    def setup(self) -> None:
        super().setup()
        self.motor.bind(self.model)

    def command(self, command: np.ndarray) -> None:
        self.command_now[:] = np.clip(command, -1.0, 1.0)
        self.motor.set_duty(self.sim.ctrl, self.command_now)

    def substep_power(self) -> np.ndarray:
        """Mean battery power over the step, W: max(Vs d i, 0) at every physics step (no regeneration)."""
        speed = self.motor.speed(self.sim.substep_sensordata)  # (n, substeps, 1)
        d = self.command_now[:, None, :]
        return np.maximum(self.motor.constants.battery_power(d, speed), 0.0).sum(axis=2).mean(axis=1)

    @property
    def channel_limits(self) -> dict[str, ChannelLimit]:
        return {k: v for k, v in self.motor.constants.channel_limits().items() if k in self.actuator_channels}

    def actuator_readings(self, sensordata: np.ndarray) -> list[np.ndarray]:
        d, speed = self.command_now[:, 0], sensordata[:, self._i_speed]
        c = self.motor.constants
        return [d, sensordata[:, self._i_angle], speed, c.torque(d, speed), c.current(d, speed)]


class ServoRig(BenchRig):
    """An AX-12 servo on the rig, commanded by goal position in counts (0..1023).

    Args:
        constants: the servo's constants and control-table settings (default: AX-12 at 10 V, factory settings).
        (the rest as :class:`BenchRig`; control at 100 Hz by default)
    """

    name = "servo"
    action_modes: ClassVar[dict[str, ActionMode]] = {
        "goal": ActionMode("goal", ("goal",), ("count",), (0.0,), (1023.0,), 100.0, "goal position, 512 = centre"),
    }
    actuator_channels: ClassVar[dict[str, str]] = {
        "goal": "count",
        "angle": "rad",
        "present_position": "count",
        "speed": "rad/s",
        "torque": "N m",
    }

    def __init__(
        self,
        control_freq: float | None = None,
        load_inertia: float = 1e-4,
        friction: float = 0.0,
        damping: float = 0.0,
        constants: ServoConstants | None = None,
        spec_edits: Sequence[SpecEdit] = (),
        num_sims: int | None = None,
        nthread: int | None = None,
        batched: bool | None = None,
    ):
        self.servo = Servo([JOINT], constants)
        super().__init__("goal", control_freq, load_inertia, friction, damping, spec_edits, num_sims, nthread, batched)

    def configure_actuator(self, spec: mujoco.MjSpec) -> None:
        self.servo.configure(spec)

    def setup(self) -> None:
        super().setup()
        self.servo.bind(self.model, self.num_sims)

    def build_parameters(self, model: mujoco.MjModel) -> ParameterMap:
        p = super().build_parameters(model)
        vs = self.servo.constants.supply_voltage
        p.add(Parameter("supply_voltage", "V", vs, 5.0, 13.0, "the servo's supply (AX-12: 7-10 V, AX-12A: 9-12 V)",
                        self.servo.supply_fields()))  # fmt: skip
        return p

    def parameters_changed(self, ids: np.ndarray) -> None:
        self.servo.motors.refresh(ids, self.field("actuator_gainprm"))

    @property
    def channel_limits(self) -> dict[str, ChannelLimit]:
        return {k: v for k, v in self.servo.constants.channel_limits().items() if k in self.actuator_channels}

    def rest_command(self, angle: np.ndarray) -> np.ndarray:
        return self.servo.constants.counts_of(angle)[:, None]

    def command(self, command: np.ndarray) -> None:
        self.command_now[:] = command
        self.servo.set_goal(self.sim.ctrl, self.command_now)

    def substep_power(self) -> np.ndarray:
        return self.servo.battery_power(self.sim.substep_sensordata).sum(axis=2).mean(axis=1)

    def actuator_readings(self, sensordata: np.ndarray) -> list[np.ndarray]:
        s = self.servo
        return [
            self.command_now[:, 0],
            sensordata[:, self._i_angle],
            s.present_position(sensordata)[:, 0],
            sensordata[:, self._i_speed],
            s.output_torque(sensordata)[:, 0],
        ]
