"""The real VelociRoACH firmware's PID arithmetic (the lab's ``pid-ip2.5.c``, ``UpdatePID``), in duty per radian::

    p = (Kp * e) >> 12;  i = (Ki * i_error) >> 12;  d = Kd * v_error
    out = ff + p + (i >> 4) + (d >> 4),  clipped to +-MAXTHROT;   i_error += e >> 4 every 1 ms tick

with ``e`` in encoder counts (65536 per leg revolution), ``v_error`` the commanded minus the measured counts per
tick, and the output in PWM counts of a 3900-count period. A regression of the real logs' duty on these terms gives
the same gains (``python -m sysid.measure``; docs/real-logs.md). The calibration's replay
(sysid/adapters/velociroach.py) and the direct measurements (sysid/adapters/velociroach_measure.py) read it from here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

COUNTS_PER_RAD = 65536 / (2 * math.pi)  # leg encoder counts (the firmware's p_state) per radian
PWM_PERIOD = 3900  # PWM counts of full duty (docs/telemetry.md)
TICK = 1e-3  # s, the firmware's PID period


def duty_gains(gains: Sequence[float]) -> dict[str, float]:
    """The firmware's integer gains [Kp, Ki, Kd, Kaw, ff] in duty per joint unit."""
    kp, ki, kd, _kaw, ff = (float(g) for g in gains)
    return {
        "kp": kp / 4096 * COUNTS_PER_RAD / PWM_PERIOD,  # duty / rad
        "ki": ki / (4096 * 16 * 16) * COUNTS_PER_RAD / TICK / PWM_PERIOD,  # duty / (rad s)
        "kd": kd / 16 * COUNTS_PER_RAD * TICK / PWM_PERIOD,  # duty / (rad/s)
        "ff": ff / PWM_PERIOD,  # duty
    }
