"""The VelociRoACH's physical effects as spec edits: the effect catalog with its bounds (what a calibration file
may hold for this robot), and the edits that apply a calibration's setting to the model (the calibrated envs, and the
calibration adapter in sysid/adapters/velociroach.py, alike)."""

from __future__ import annotations

import math

import mujoco

from envs.actuators.dcmotor import GAIN_K, GAIN_R
from envs.common.edits import add_periodic_torque, delay_actuators, scale_mass
from envs.common.effects import TEMPLATES, Effect, Setting, make
from envs.velociroach import constants
from envs.velociroach.constants import SIDES


# --- the effects, applied by calibration and by the calibrated envs alike ---------------------------------------
def roach_effects(dt: float) -> dict[str, Effect]:
    """The VelociRoACH's catalog effects with their bounds (nominal values are the model's; see docs/velociroach.md).
    Ranges: the crank's Coulomb friction up to 1.4 times the motor's stall torque at the crank (11 mN m at 3.7 V: the
    2 Hz log's right leg stands stalled at full duty); its viscous friction up to three times the motor's own back-EMF
    damping (2.9e-5 N m s/rad); rotor inertia up to 70 times the assumed 1.5e-9 kg m^2; the motor constant from 0.3 to
    4 times the lab script's 1.41 mN m/A (the real logs' back-EMF is 1.7 to 2.4 times the model's:
    docs/calibration.md); the back-EMF reading's offset +-0.3 V (the board subtracts an offset measured at start-up)
    and its scale from half to three times (the logs' conversion is the lab script's, uncalibrated)."""
    # what the leg channels barely see (Effect.weak): at each range's far end the nominal model's error is mostly
    # under 3 noise levels against the true model's replay floor (the matrix benchmark measures it), where the
    # others reach 4 to 20
    rotor = ("the rotor's inertia torque at the logged strides stays under the duty's noise and the replay floor "
             "(it grows with the stride frequency squared: a log above 12 Hz shows more)")  # fmt: skip
    body = ("acts on the body, which the log does not hold: the legs feel it only through stance loads, under the "
            "replay floor that the body's unknown state sets")  # fmt: skip
    floor = ("acts on the body, which the log does not hold: the legs see it against the nominal model's replay "
             "floor, but the true model's own replay diverges about as much: the gain hides in its floor")  # fmt: skip
    supply = ("the firmware's PID closes the loop around the logged battery voltage: a supply 20% off changes only "
              "the duty, by a fifth of its small mean")  # fmt: skip
    light = ("the nominal model's legs need little duty (a tenth at 2 Hz): a reading coupled to so small a duty "
             "stays near the replay floor on its own synthetic logs; the real logs run at three to four times the "
             "duty")  # fmt: skip
    stance = ("the nominal model's legs carry little load (a tenth of the duty at 2 Hz): the stride pattern of their "
              "small tracking error, which a phase shifts, stays near the replay floor on its own synthetic logs; the "
              "real 2 Hz log, at three to four times the duty, shows it")  # fmt: skip
    out: list[Effect] = [make("delay", seconds=(0.0, 0.0, 0.02, dt))]
    for side in SIDES:
        out += [
            make("coulomb_friction", side, torque=(0.0, 0.0, 15e-3)),
            make("viscous_friction", side, damping=(0.0, 0.0, 1e-4)),
            make("armature", side, inertia=(0.0, 0.0, 1e-7), weak=rotor),
            make("torque_constant", side, scale=(1.0, 0.3, 4.0)),
            make("sensor_bias", f"bemf_{side}", offset=(0.0, -0.3, 0.3)),
        ]
    out += [
        make("supply_voltage", scale=(1.0, 0.8, 1.2), weak=supply),
        # foot friction and mass act on the body: a heavier or grippier roach's own replay diverges more, so the
        # true model's replay floor swallows them (docs/calibration.md, "Why some effects are weak"). They reach the
        # legs mostly through where the carried body is when a segment starts, so they are declared carried
        make("foot_friction", mu=(0.4, 0.05, 1.5), carried=True, weak=floor),
        make("ground_contact", timeconst=(0.002, 0.001, 0.02), dampratio=(1.0, 0.2, 2.0), weak=body),
        make("leg_stiffness", scale=(1.0, 0.3, 3.0), weak=body),
        make("mass", scale=(1.0, 0.5, 2.0), carried=True, weak=floor),
        make("com_offset", x=(0.0, -0.02, 0.02), weak=body),
    ]
    # after the effects above, so that their places in the catalog (and the calibration matrix's seeds) stay
    for side in SIDES:
        out += [
            # gears and the planarizing linkage: a small spur train passes 0.5-0.8 of the torque per stage pair
            # and the linkage loses more; down to 0.15, since the real logs' duty asks for a drive a third as strong
            # at a back-EMF twice the model's (python -m sysid.measure, docs/real-logs.md)
            # not weak: at 0.15 the nominal model's error on its own synthetic logs reaches 3.07, just over the
            # threshold of 3 (python -m benchmarks.calibration_matrix --kinds weak); a drawn value nearer 1 barely shows
            make("gearbox_efficiency", side, efficiency=(1.0, 0.15, 1.0)),
            # the board samples the back-EMF in the PWM off-time; measured directly on the real logs, -0.2 to -0.6 V
            # per unit duty (python -m sysid.measure)
            make("sensor_coupling", f"bemf_{side}", per_unit=(0.0, -1.0, 0.5), weak=light),
        ]
    for side in SIDES:
        # the back-EMF reading's scale: the logs' volts come from the lab's scaling script (3.3 V over 1024 counts
        # through a 15/47 divider, docs/telemetry.md), and no log holds a calibration of the board's divider and
        # sampling. The 2015 logs read 1.7 to 2.4 times the model's back-EMF per leg speed, and at 13 Hz the right
        # side reads more than the voltage its driver applies (python -m sysid.measure): a motor constant that large
        # or a reading that overstates. From half to three times, past the largest ratio measured
        out.append(make("sensor_gain", f"bemf_{side}", scale=(1.0, 0.5, 3.0)))
    out += [
        # ridges up to 3 cm: about twice the C-leg's 13.4 mm diameter (assets/velociroach/cleg.xml), obstacles of
        # the 13 Hz log's kind; lower ones barely reach the leg channels through the body
        make("terrain_bump", height=(0.0, 0.0, 0.03)),
        make("disturbance", torque=(0.0, 0.0, 2e-3), frequency=(3.0, 0.5, 10.0)),
    ]
    for side in SIDES:
        # where the legs are at a reading of the crank's encoder: the sources give neither the magnet's mounting on
        # the crank nor the linkage's phase against it, and the model's stand-in linkage (assets/velociroach) puts
        # tripod A's mid-stance at its own zero. Any phase, a full turn: on the 2 Hz real log the model's
        # stride-periodic tracking error runs against the robot's (python -m sysid.measure, docs/real-logs.md)
        # weak: the nominal model's legs carry so little load that their error against the clock, the pattern it
        # shifts, is a few degrees; on its own synthetic logs it reaches 1.4-1.7 noise levels (python -m
        # benchmarks.calibration_matrix --robots roach --kinds effect --effects leg_phase_left leg_phase_right)
        out.append(make("leg_phase", side, offset=(0.0, -math.pi, math.pi), weak=stance))
    for side in SIDES:
        # a load that depends on where the crank is: the real robot's linkage is a folded laminate whose flexure
        # hinges bend and spring back as the crank turns [roach-sim: "planarizing four-bar linkages"], which the
        # model's rigid hinges lack, and the legs' stance load the model's contacts may give another shape. On the
        # 2 Hz real log the duty swings between 0.1 and 0.6 with the crank's angle, the same at every stride (the
        # nominal model's between 0.0 and 0.16): fitted, a first harmonic of 2.7 +- 1.1 mN m on its right crank, a
        # second of 2.3 +- 1.1 mN m on its left (docs/real-logs.md). Each coefficient up to half the motor's stall
        # torque at the crank (11 mN m at 3.7 V)
        load = dict.fromkeys((p.name for p in TEMPLATES["periodic_load"].params), (0.0, -5.5e-3, 5.5e-3))
        out.append(make("periodic_load", side, **load))
    for side in SIDES:
        # the back-EMF reading's offset while the firmware's clock runs: on the 2015 logs the running reading lies
        # 0.02-0.04 V (2 Hz) and up to 0.27 V [0.12, 0.61] (13 Hz, left) above its line through zero while the
        # reading at rest is -5 to -7 mV (python -m sysid.measure: bemf_intercept, bemf_at_rest;
        # docs/real-logs.md). To 0.6 V, past the largest measured; down to -0.2 V for a reading that sags instead
        out.append(make("sensor_running_offset", f"bemf_{side}", offset=(0.0, -0.2, 0.6)))
    return {e.name: e for e in out}


def effects_edit(setting: Setting):
    """Spec edit of a setting's model effects (calibration and the calibrated envs alike), added to the nominal
    spec's values: each crank's Coulomb and viscous friction and its reading's phase against the legs, each motor's
    rotor inertia, motor constant and gearbox efficiency (as its winding resistance over the efficiency), the
    feet's and floor's friction, the floor's contact time constant and damping ratio, the C-legs' stiffness, and the
    chassis' mass (its inertia with it) and centre of mass (its inertial written explicitly, from the compiled
    nominal body), and each crank's periodic load (tendon springs, :func:`~envs.common.edits.add_periodic_torque`)."""

    def edit(spec: mujoco.MjSpec) -> None:
        for side in SIDES:
            crank = spec.joint(constants.CRANK_JOINTS[side])
            crank.frictionloss += setting.get(f"coulomb_friction_{side}.torque", 0.0)
            # the legs ahead of the crank's reading: the joint's value (what its encoder, the firmware and the
            # telemetry read) is its turn from the model's zero less its reference, and the linkage's equalities
            # follow the turn
            crank.ref -= setting.get(f"leg_phase_{side}.offset", 0.0)
            crank.damping[0] += setting.get(f"viscous_friction_{side}.damping", 0.0)
            motor = spec.actuator(constants.MOTORS[side])
            motor.armature += setting.get(f"armature_{side}.inertia", 0.0)
            motor.gainprm[GAIN_K] *= setting.get(f"torque_constant_{side}.scale", 1.0)
            motor.gainprm[GAIN_R] /= setting.get(f"gearbox_efficiency_{side}.efficiency", 1.0)
        if "foot_friction.mu" in setting:
            for geom in spec.geoms:
                body = geom.parent
                if geom.name == constants.FLOOR_GEOM or (body is not None and body.name.endswith("_leg")):
                    geom.friction[0] = setting["foot_friction.mu"]
        floor = spec.geom(constants.FLOOR_GEOM)
        if floor is not None:
            floor.solref = [setting.get("ground_contact.timeconst", floor.solref[0]),
                            setting.get("ground_contact.dampratio", floor.solref[1])]  # fmt: skip
        stiffness = setting.get("leg_stiffness.scale", 1.0)
        for joint in spec.joints:
            if joint.name.endswith("_spring"):
                joint.stiffness[0] *= stiffness
        scale_mass(spec, [constants.ROOT_BODY], setting.get("mass.scale", 1.0), setting.get("com_offset.x", 0.0))
        for side in SIDES:  # last: its springs are placed from the crank's reference, which a leg phase moves
            harmonics = periodic_load(setting, side)
            if harmonics:
                add_periodic_torque(spec, constants.CRANK_JOINTS[side], harmonics)

    return edit


def periodic_load(setting: Setting, side: str) -> dict[int, tuple[float, float]]:
    """A setting's periodic load on a side's crank, {harmonic: (sin, cos)} (N m), the harmonics it holds (none: the
    model has no springs for it, so that a setting without the effect compiles the nominal model's sizes)."""
    out = {}
    for h in (1, 2):
        s, c = (float(setting.get(f"periodic_load_{side}.{f}{h}", 0.0)) for f in ("sin", "cos"))
        if s or c:
            out[h] = (s, c)
    return out


def delay_edit(seconds: float):
    """Spec edit of the calibrated envs: both motors' inputs delayed by ``seconds``, as the replay shifts the logged
    commands."""
    return delay_actuators(seconds, [constants.MOTORS[side] for side in SIDES])
