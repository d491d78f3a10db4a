"""The Bioloid's kick (envs/bioloid/kick.py): its goals, and what it does to a ball on the model."""

import gymnasium as gym
import numpy as np
import pytest

from benchmarks.bioloid_kick import kick_once
from envs.bioloid import constants
from envs.bioloid.kick import KICK_AHEAD, KICK_SIDE, LEFT, RIGHT, Kick
from envs.soccer.academy import version


def test_a_kick_starts_and_ends_in_the_ready_posture_and_the_left_one_mirrors_the_right():
    kick = Kick()
    ends = kick.counts(np.array([0.0, kick.duration, kick.duration + 1.0, -1.0]), np.full(4, RIGHT))
    np.testing.assert_allclose(ends, np.tile(kick.ready, (4, 1)), atol=1e-9)
    t = np.linspace(0.0, kick.duration, 50)
    right, left = kick.counts(t, np.full(50, RIGHT)), kick.counts(t, np.full(50, LEFT))
    mirror = {"F_L": "F_R", "F_R": "F_L", "B_L": "B_R", "B_R": "B_L"}
    for leg, other in mirror.items():
        for joint in (constants.HIP, constants.KNEE):
            a, b = constants.SERVO_INDEX[joint[leg]], constants.SERVO_INDEX[joint[other]]
            np.testing.assert_allclose(left[:, a], right[:, b], atol=1e-9)
    kicker = constants.SERVO_INDEX[constants.HIP["F_R"]]
    assert np.ptp(right[:, kicker]) > np.ptp(right[:, constants.SERVO_INDEX[constants.HIP["F_L"]]]), "it swings"


@pytest.mark.parametrize("side", [RIGHT, LEFT])
def test_a_ball_in_the_kick_zone_goes_forward_fast_and_the_robot_stays_up(side):
    """From the ready posture, a ball at rest in front of the kicking foot (the zone's near end, where the strike
    is hardest) leaves at 2 m/s or more within 15 deg of straight ahead, thirty to fifty times as fast as the trot
    pushes it, and the robot does not fall."""
    env = gym.make(f"skitter/BioloidScoreEmptyGoal-v{version('Bioloid')}")
    result = kick_once(env, Kick(), side, KICK_AHEAD[0], KICK_SIDE, seed=0)
    env.close()
    assert not result["fell"]
    assert result["speed"] >= 2.0 and abs(result["direction"]) <= 15.0
