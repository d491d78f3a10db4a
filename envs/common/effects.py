"""The effect catalog: what a model may lack, each a named, bounded set of parameters with a signature and an alias
group.

An effect is declared here once, generically (its parameters' units and what it looks like in the residual
diagnostics); each robot says which effects it can take, on what (a joint, a side, a channel) and with which bounds
(``envs/<robot>/effects.py``, with the spec edits that apply them to its model), and its calibration adapter
(sysid/adapters) how the rest act in a replay (a change of the controls it replays, a wrapper on a predicted sensor
channel). Effects that alias each other on a robot's channels
share an ``alias`` group: the data cannot tell them apart, and a calibration that picks one of a group has found the
group.

Out-of-catalog effects (``catalogued=False``) exist only to be injected by the synthetic-data generator: a terrain
bump and a periodic disturbance torque. Calibration never offers them, so data that holds one must come out
unexplained.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

Setting = Mapping[str, float]  # effect parameter (``effect.param``) -> value: a point of the effects' space


@dataclass(frozen=True)
class Param:
    """One parameter of an effect: its unit, value with no effect (``nominal``), and the range it may take."""

    name: str
    unit: str
    nominal: float
    low: float
    high: float
    smooth: bool = True  # False: fitted by a grid and CMA-ES (a delay in whole steps, a deadband)
    step: float = 0.0  # the finest difference that matters (non-smooth ones); 0: a two-thousandth of the range
    # a shape, not a strength (a disturbance's frequency): at its nominal value the effect is not absent, so the
    # generator draws it anywhere in its range rather than pushing it away from nominal to make the effect show
    shape: bool = False
    carried: bool = False  # its effect's (Effect.carried): fits measure it with its own carried state
    # a scale over a decade or more (a stiffness from a tenth to ten times nominal): the ranking's grid across its
    # range is geometric, as evenly spread in the ratio as a linear grid is in the difference (select.score)
    log: bool = False
    # an angle whose range is one whole turn, its two ends one point: the ranking spaces its grid around the turn, a
    # fit at an end is not pushing against anything, and its basins are as narrow as the pattern it shifts
    periodic: bool = False

    @property
    def span(self) -> float:
        return self.high - self.low

    @property
    def resolution(self) -> float:
        return self.step if self.step > 0 else self.span / 2000 if self.span > 0 else 1.0


@dataclass(frozen=True)
class Effect:
    """A named effect with bounded parameters; ``target`` names what it acts on (a joint, a side, a channel)."""

    name: str
    params: tuple[Param, ...]
    alias: str
    signature: str
    description: str
    target: str = ""
    catalogued: bool = True
    meta: Mapping[str, object] = field(default_factory=dict)
    # why this robot's channels barely see the effect ("" if they do): even at the far end of its range, under the
    # synthetic excitation, the nominal model's error stays under three noise levels. Still offered to selection (a
    # livelier log may show it); the matrix reports it apart, and a test holds the declaration to the data.
    weak: str = ""
    # the effect reaches the logged channels mostly through state the log does not hold and a replay carries from
    # segment to segment (a legged robot's body: its mass, its feet on the ground). With the carried state held at
    # the anchor's, as a fit's local steps hold it, such an effect barely moves the residual, so the ranking also
    # measures its grid points with their own carried state (select.score)
    carried: bool = False

    @property
    def observable(self) -> bool:
        return not self.weak

    @property
    def smooth(self) -> bool:
        return all(p.smooth for p in self.params)

    def key(self, param: str) -> str:
        """The flat name of one parameter: ``effect.param``."""
        return f"{self.name}.{param}"

    def nominal(self) -> dict[str, float]:
        return {self.key(p.name): p.nominal for p in self.params}


# --- the generic declarations (bounds are the adapter's) ------------------------------------------------------------
# alias groups: Coulomb friction, backlash and deadband look alike near zero speed; torque constant, supply voltage and
# mass (inertia) trade off against each other; delay and armature both slow the response; sensor bias and offsets.
GROUP_STICTION = "stiction: coulomb friction / backlash / deadband"
GROUP_DRIVE = "drive strength: torque constant / supply voltage / load inertia or mass"
GROUP_LAG = "lag: delay / armature"
TEMPLATES: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "delay",
            (Param("seconds", "s", 0.0, 0.0, 0.05, smooth=False),),
            GROUP_LAG,
            "cross-correlation of command and residual peaks at a positive lag; residual leads the motion",
            "the actuator acts on the command a fixed time late (MuJoCo's actuator delay, or a shifted command)",
        ),
        Effect(
            "coulomb_friction",
            (Param("torque", "N m", 0.0, 0.0, 1.0),),
            GROUP_STICTION,
            "residual torque follows the sign of velocity; largest near reversals and at low speed",
            "dry friction on a joint (MuJoCo frictionloss)",
        ),
        Effect(
            "viscous_friction",
            (Param("damping", "N m s/rad", 0.0, 0.0, 1.0),),
            "viscous friction",
            "residual grows in proportion to speed",
            "viscous damping on a joint",
        ),
        Effect(
            "stribeck_friction",
            (Param("static", "N m", 0.0, 0.0, 1.0), Param("velocity", "rad/s", 0.5, 0.1, 2.5, shape=True)),
            "Stribeck friction",
            "moves start late and stop short of the goal: residual near zero speed only, gone at speed",
            "static friction above the Coulomb level that decays with speed (static exp(-(w / velocity)^2)): the "
            "Stribeck effect, natively as MuJoCo's LuGre friction",
        ),
        Effect(
            "asymmetric_friction",
            (Param("positive", "N m", 0.0, 0.0, 1.0), Param("negative", "N m", 0.0, 0.0, 1.0)),
            GROUP_STICTION,
            "steady error and speed differ between the two directions of motion",
            "Coulomb friction that differs by direction: one level against positive speed, another against negative "
            "(their mean a frictionloss, half their difference a constant torque); equal levels are Coulomb friction",
        ),
        Effect(
            "load_friction",
            (Param("coefficient", "1", 0.0, 0.0, 0.5),),
            "load-dependent friction",
            "starts slower and stops harder than the model: residual follows the torque the gearbox carries",
            "friction that grows with the torque the gearbox transmits (coefficient x |torque|): less torque out "
            "while the motor drives the load, more braking while the load drives the gearbox",
        ),
        Effect(
            "backlash",
            (Param("gap", "rad", 0.0, 0.0, 0.2, smooth=False),),
            GROUP_STICTION,
            "position residual jumps at velocity reversals, then settles: a dead zone between motor and load",
            "play between the motor and its load (a free joint of limited range between them)",
        ),
        Effect(
            "deadband",
            (Param("duty", "1", 0.0, 0.0, 0.2, smooth=False),),
            GROUP_STICTION,
            "no motion for small commands; residual at low commands only",
            "the driver outputs nothing below a duty threshold and subtracts it above",
        ),
        Effect(
            "torque_constant",
            (Param("scale", "1", 1.0, 0.3, 2.0),),
            GROUP_DRIVE,
            "residual proportional to the commanded torque; acceleration too high or low throughout",
            "the motor's torque per ampere, scaled (with it, the back-EMF constant of an ideal motor)",
        ),
        Effect(
            "back_emf_constant",
            (Param("scale", "1", 1.0, 0.3, 2.0),),
            "top speed",
            "steady speed wrong in proportion to the supply, transients right",
            "the motor's back-EMF per unit speed, scaled",
        ),
        Effect(
            "supply_voltage",
            (Param("scale", "1", 1.0, 0.5, 1.5),),
            GROUP_DRIVE,
            "speed and torque limits both off by one factor",
            "the supply voltage, scaled (a different battery, or the drop of a wire or driver)",
        ),
        Effect(
            "supply_sag",
            (Param("resistance", "ohm", 0.0, 0.0, 2.0),),
            "supply sag",
            "residual grows with the current drawn: largest on hard accelerations",
            "the battery's internal resistance: the supply drops by resistance x current",
        ),
        Effect(
            "pwm_decay",
            (Param("coast", "1", 0.0, 0.0, 1.0),),
            "driver decay mode",
            "steady speed concave in the duty, saturating well below full duty; slow to brake when the duty drops",
            "how the H-bridge spends the PWM off-time: 0 shorts the motor (slow decay, the back-EMF brakes all the "
            "time), 1 lets it coast (fast decay: current flows, and the back-EMF brakes, only during the on-time)",
        ),
        Effect(
            "gearbox_efficiency",
            (Param("efficiency", "1", 1.0, 0.15, 1.0),),
            "drive losses",
            "the drive needs more duty for its torque than the motor's constants say, while its back-EMF reads right",
            "the fraction of the motor's torque the gearbox and linkage pass on (driving and driven alike); to the "
            "motor's circuit the same as a winding resistance of 1/efficiency times nominal",
        ),
        Effect(
            "periodic_load",
            tuple(Param(f"{f}{h}", "N m", 0.0, -1.0, 1.0) for h in (1, 2) for f in ("sin", "cos")),
            "periodic load",
            "a residual on the drive that repeats with the crank's angle, the same at every stride: the duty rises "
            "and falls at the same readings of the angle whatever the speed",
            "a torque on a crank that depends on where the crank is, sin1 sin(q) + cos1 cos(q) + sin2 sin(2q) + "
            "cos2 cos(2q) at its reading q: a linkage's flexure hinges, which bend and spring back as the crank "
            "turns, or the legs' stance load in a shape the contacts miss (tendon springs on joints geared 1:1 and "
            "2:1 to the crank)",
        ),
        Effect(
            "leg_phase",
            (Param("offset", "rad", 0.0, -math.pi, math.pi, periodic=True),),
            "leg phase",
            "a stride-periodic residual, its pattern shifted along the stride: the legs meet the ground at another "
            "reading of their angle",
            "where the legs are at a reading of the leg angle: the encoder's zero against the legs (a magnet's or a "
            "leg's mounting), the legs that far ahead of the reading",
        ),
        Effect(
            "sensor_coupling",
            (Param("per_unit", "channel unit", 0.0, -1.0, 1.0),),
            "sensor coupling",
            "a residual on one channel that follows the duty",
            "a measured channel reads the duty times a coefficient besides its own quantity (a back-EMF sampled while "
            "the drive's current still decays reads lower the longer the pulse)",
        ),
        Effect(
            "sensor_running_offset",
            (Param("offset", "channel unit", 0.0, -1.0, 1.0),),
            "sensor offset while running",
            "a constant residual on one channel while the drive runs, none at rest",
            "a measured channel reads an offset only while the drive switches (a back-EMF sampled while the "
            "winding's current still flows through the bridge reads above its line through zero)",
        ),
        Effect(
            "armature",
            (Param("inertia", "kg m^2", 0.0, 0.0, 1.0),),
            GROUP_LAG,
            "residual proportional to acceleration",
            "extra rotor inertia reflected to the joint",
        ),
        Effect(
            "servo_gain",
            (Param("scale", "1", 1.0, 0.25, 4.0),),
            "servo stiffness",
            "steady error under load and settling speed both off: the compliance slope",
            "the servo's proportional gain (its compliance slope), scaled",
        ),
        Effect(
            "foot_friction",
            (Param("mu", "1", 0.4, 0.05, 1.5),),
            "ground contact",
            "stance legs slip or stick: residual in stance, not in swing",
            "sliding friction between feet and ground",
        ),
        Effect(
            "ground_contact",
            (Param("timeconst", "s", 0.002, 0.001, 0.02), Param("dampratio", "1", 1.0, 0.2, 2.0)),
            "ground contact",
            "residual at touchdown, at the stride frequency and its harmonics",
            "the ground's stiffness and damping (MuJoCo solref of the floor)",
        ),
        Effect(
            "leg_stiffness",
            (Param("scale", "1", 1.0, 0.3, 3.0),),
            "leg stiffness",
            "residual in stance at the body's bounce frequency",
            "the legs' stiffness, scaled",
        ),
        Effect(
            "spine_stiffness",
            (Param("scale", "1", 1.0, 0.1, 10.0),),
            "spine stiffness",
            "residual at the body's pitch and roll modes; legs' loads shift between segments",
            "a segmented body's spine stiffness (every joint and axis), scaled",
        ),
        Effect(
            "mass",
            (Param("scale", "1", 1.0, 0.5, 2.0),),
            GROUP_DRIVE,
            "residual proportional to the body's acceleration and the motors' load",
            "the body's mass (and inertia), scaled",
        ),
        Effect(
            "com_offset",
            (Param("x", "m", 0.0, -0.02, 0.02),),
            "centre of mass",
            "a steady pitch and asymmetric front/back loading",
            "the body's centre of mass moved along x",
        ),
        Effect(
            "sensor_bias",
            (Param("offset", "channel unit", 0.0, -1.0, 1.0),),
            "sensor offset",
            "a constant residual on one channel",
            "a constant offset on a measured channel",
        ),
        Effect(
            "sensor_gain",
            (Param("scale", "1", 1.0, 0.5, 2.0),),
            "sensor gain",
            "residual proportional to the channel's value",
            "a scale error on a measured channel",
        ),
        # out of catalog: for the synthetic-data generator only
        Effect(
            "terrain_bump",
            (Param("height", "m", 0.0, 0.0, 0.01),),
            "out of catalog",
            "a transient where the robot crosses it",
            "a bump in the floor across the robot's path",
            catalogued=False,
        ),
        Effect(
            "disturbance",
            (Param("torque", "N m", 0.0, 0.0, 1.0), Param("frequency", "Hz", 3.0, 0.5, 10.0, shape=True)),
            "out of catalog",
            "a spectral peak at the disturbance's frequency, unrelated to the command",
            "a periodic torque on the body or load, from outside the model",
            catalogued=False,
        ),
    )
}


def make(
    name: str,
    target: str = "",
    alias: str | None = None,
    weak: str = "",
    carried: bool = False,
    log: bool = False,
    **bounds: tuple[float, ...],
) -> Effect:
    """A robot's instance of a catalog effect: ``bounds`` gives (nominal, low, high) per parameter, or (nominal,
    low, high, step) with the finest step that matters (a delay's physics step); the name gets the target as a
    suffix (``coulomb_friction_left``); ``weak`` says why the robot's channels barely see it (``Effect.weak``);
    ``carried`` that it acts through the state a replay carries over (``Effect.carried``); ``log`` that its
    parameters are scales over decades, ranked on a geometric grid (``Param.log``)."""
    template = TEMPLATES[name]
    params = []
    for p in template.params:
        if p.name in bounds:
            nominal, low, high, *step = bounds[p.name]
            p = replace(p, nominal=nominal, low=low, high=high, step=step[0] if step else p.step)
        if log and not 0 < p.low < p.high:
            raise ValueError(f"{name}.{p.name}: a log scale needs 0 < low < high, got [{p.low}, {p.high}]")
        params.append(replace(p, carried=carried, log=log))
    full = f"{name}_{target}" if target else name
    return replace(template, name=full, params=tuple(params), target=target, alias=alias or template.alias,
                   weak=weak, carried=carried)  # fmt: skip


def base_name(effect: Effect) -> str:
    """The catalog name of a robot's effect (``coulomb_friction`` for ``coulomb_friction_left``)."""
    return effect.name[: -len(effect.target) - 1] if effect.target else effect.name
