"""The Bioloid's physical effects as spec edits: the effect catalog with its bounds (what a calibration file may
hold for this robot), and the edits that apply a calibration's setting to the model (the calibrated envs, and the
calibration adapter in sysid/adapters/bioloid.py, alike)."""

from __future__ import annotations

import mujoco
import numpy as np

from envs.actuators.dcmotor import GAIN_KP, GAIN_VMAX
from envs.bioloid import constants
from envs.common.edits import delay_actuators, scale_mass
from envs.common.effects import Effect, Setting, make

PLAY = "play"  # the backlash joint of each servo: <servo>_play
SERVO_TOP_SPEED = "servo top speed: viscous friction / supply voltage"
SIDE_SERVOS = {
    side: tuple(
        servo
        for leg in constants.LEGS
        if constants.LEG_SIDE[leg] == side
        for servo in (constants.HIP[leg], constants.ABDUCTION[leg], constants.KNEE[leg])
    )
    for side in constants.SIDES
}


# why the 16 positions barely see an effect (Effect.weak; measured: the matrix's weak cases, the nominal model's
# error at the range's far end, median of three seeds): the servos' position loop holds a joint within a few counts
# of its goal whatever resists it, and the body the log lacks sets a replay floor of half a count
HIDDEN_BY_THE_LOOP = ("the servo's position loop (0.05 N m per count) hides it: at the range's far end it shifts a "
                      "moving servo by a few counts, within the replay floor (nominal error 1.2-1.9)")  # fmt: skip
THROUGH_THE_BODY = ("it acts through the body, which the log lacks: the servos' stiff position loops pass its load to "
                    "their positions as a count or two, within the replay floor (nominal error 1.0-1.5 at the range's "
                    "far end, one seed)")  # fmt: skip


def bioloid_effects(dt: float) -> dict[str, Effect]:
    """The Bioloid's catalog effects and their bounds. Ranges: dry friction up to an eighth of the AX-12's 1.62 N m
    stall torque at 10 V and viscous friction up to a third of its own back-EMF damping (stall torque over no-load
    speed: 1.62 / 5.3 = 0.30 N m s/rad) per joint; rotor inertia up to three times the assumed 1.5e-8 kg m^2 x 254^2
    = 9.7e-4 kg m^2 at the joint; the compliance slope from a quarter to four times the factory 32 counts (the
    control table's 2..128 range, ROBOTIS); the supply 20% either way (a 9.6 V pack from full to flat); a worn
    gear train's play up to 0.05 rad (3 deg); the CM-5's mass +-20% (a different battery; the robot's own parameter
    range, envs/bioloid/robot.py) and its centre of mass 2 cm either way (the report suspects it is off,
    [bioloid-webots, V.B]); a position offset up to 20 counts (a horn mounted a spline off)."""
    out: list[Effect] = [
        make("delay", seconds=(0.0, 0.0, 0.05, dt)),
        make("backlash", gap=(0.0, 0.0, 0.05)),
        make("servo_gain", scale=(1.0, 0.25, 4.0)),
        make("supply_voltage", scale=(1.0, 0.8, 1.2), alias=SERVO_TOP_SPEED),
        make("armature", inertia=(0.0, 0.0, 2e-3), weak=HIDDEN_BY_THE_LOOP),
    ]
    for side in constants.SIDES:
        out += [
            make("coulomb_friction", side, torque=(0.0, 0.0, 0.2), weak=HIDDEN_BY_THE_LOOP),
            make("viscous_friction", side, alias=SERVO_TOP_SPEED, damping=(0.0, 0.0, 0.1), weak=HIDDEN_BY_THE_LOOP),
            make("sensor_bias", f"position_{side}", offset=(0.0, -20.0, 20.0)),
        ]
    out += [
        make("foot_friction", mu=(0.8, 0.2, 1.5), weak=THROUGH_THE_BODY),
        make("ground_contact", timeconst=(0.004, 0.004, 0.03), dampratio=(1.0, 0.3, 2.0), weak=THROUGH_THE_BODY),
        make("mass", scale=(1.0, 0.8, 1.2), weak=THROUGH_THE_BODY),
        make("com_offset", x=(0.0, -0.02, 0.02), weak=THROUGH_THE_BODY),
        # ridges up to 8 cm: under half the leg's 0.175 m reach ([bioloid-webots, VI.A]: L1 0.09 + L2 0.085 m), an
        # obstacle its feet step onto; the 16 servo positions barely see the body, so lower ridges hardly show
        make("terrain_bump", height=(0.0, 0.0, 0.08)),
        make("disturbance", torque=(0.0, 0.0, 3.0), frequency=(3.0, 0.5, 10.0)),
    ]
    return {e.name: e for e in out}


def effects_edit(setting: Setting):
    """Spec edit of a setting's model effects (calibration and the calibrated envs alike), after the servos are
    configured: per side the joints' Coulomb and viscous friction; every servo's rotor inertia, gain and supply
    (the amplifier's torque-space gains and bound scale with the supply, envs/actuators/dcmotor.py); the crutches'
    friction and contact; BODY's mass and centre of mass."""

    def edit(spec: mujoco.MjSpec) -> None:
        for side in constants.SIDES:
            for servo in SIDE_SERVOS[side]:
                joint = spec.joint(servo)
                joint.frictionloss += setting.get(f"coulomb_friction_{side}.torque", 0.0)
                joint.damping[0] += setting.get(f"viscous_friction_{side}.damping", 0.0)
        inertia = setting.get("armature.inertia", 0.0)
        gain, supply = setting.get("servo_gain.scale", 1.0), setting.get("supply_voltage.scale", 1.0)
        for servo in constants.SERVOS:
            spec.joint(servo).armature += inertia
            a = spec.actuator(f"{servo}_servo")
            a.gainprm[GAIN_KP] *= gain * supply
            a.gainprm[GAIN_VMAX] *= supply
        feet = {constants.FOOT_GEOM[leg] for leg in constants.LEGS} | {
            constants.CRUTCH_GEOM[leg] for leg in constants.LEGS
        }
        for geom in spec.geoms:
            if geom.name in feet:
                if "foot_friction.mu" in setting:
                    geom.friction[0] = setting["foot_friction.mu"]
                if "ground_contact.timeconst" in setting:
                    geom.solref = [setting["ground_contact.timeconst"], setting.get("ground_contact.dampratio", 1.0)]
        scale_mass(spec, [constants.ROOT_BODY], setting.get("mass.scale", 1.0), setting.get("com_offset.x", 0.0))

    return edit


def add_backlash(gap: float):
    """Spec edit: on each servo's bracket, a second hinge on the servo's axis free within +-gap/2 (the gear train's
    play); the servo's potentiometer reads the output shaft (the servo joint), the bracket hangs on the play."""

    def edit(spec: mujoco.MjSpec) -> None:
        for servo in constants.SERVOS:
            axis = np.array(spec.joint(servo).axis, dtype=float)
            play = spec.body(servo).add_joint(name=f"{servo}_{PLAY}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis)
            play.range = [-gap / 2, gap / 2]
            play.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            play.armature = 1e-6  # the bracket's own inertia carries it; a little keeps the free play well posed

    return edit


def delay_edit(seconds: float):
    """Spec edit of the calibrated envs: every servo's goal delayed by ``seconds``, as the replay shifts the logged
    goals."""
    return delay_actuators(seconds, [f"{servo}_servo" for servo in constants.SERVOS])
