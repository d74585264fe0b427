"""The snapshot's carried-shift variance against the simulated odometry, for a fix's uneven reads.

A fix's ranges are carried to its last one by the dead-reckoned shift
(:mod:`estimators.fault.carried`); :func:`estimators.fault.carried.shift_var` gives the variance
of that shift's error, which the snapshot's covariance (and so the coverage check) includes.
The odometry draws its random slip per read, with std ``odometry_noise |d_w|`` for the read's
wheel travel ``d_w``; in an episode a fix's measurement reads fall between the control ticks
(``sim.episode.drive``), so the increments over a shift are unequal, and ``d^2 / (2 n)`` for
``n`` equal ones understates ``sum (d_l^2 + d_r^2) / 4``. That was the overconfidence of the
random world ``random-7-008`` (coverage 0.9427 of 46,397 fixes at 200 runs, issue 23).

Here the odometry (:class:`sim.physics.odometry.WheelOdometry`) reads wheels rolling straight at
1 m/s with the episode's pattern: control reads every ``CONTROL_STEPS`` physics steps and a fix's
measurement reads at the physics steps they fall due (one on a control tick: a read of zero
travel). Encoders of 2^24 ticks make the quantisation negligible (its ``tick^2 / 12`` is kept in
the claim), so each trial's along-track shift error is gaussian with the claimed variance and
``sum z^2`` over ``N`` independent trials is chi2(N): the acceptance region is its two-sided
interval at false-alarm probability ``ALPHA``. Negative control: the equal-increment claim
(``slip_weight`` not given) for the same reads lies outside it (its variance is 0.75 of the
realised one here; the interval is +-7.5 %).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import stats

import scenarios
from estimators.fault.carried import shift_var
from sim.episode.drive import CONTROL_STEPS
from sim.physics.config import PhysicsConfig

ALPHA = 0.001
N = 4000
SPEED = 1.0
MEASUREMENT_TIME = 0.027   # random-7-008's


def _trials(robot, first_step: int):
    """Dead-reckon N shifts from a fix's first measurement read to its last; return errors and claims."""
    from sim.physics.odometry import WheelOdometry

    dt = PhysicsConfig().time_step
    k = 3
    due = [first_step + math.ceil(j * MEASUREMENT_TIME / dt - 1e-9) for j in range(k)]
    ticks = set(range(0, due[-1] + 1, CONTROL_STEPS))
    reads = sorted(ticks | set(due))    # a measurement on a control tick reads twice
    reads += [s for s in due if s in ticks]
    reads.sort()
    reads = [s for s in reads if s >= due[0]]
    rng = np.random.default_rng(20261203)
    omega = SPEED / robot.wheel_radius
    errors, claims, equal = [], [], []
    for _ in range(N):
        a0 = rng.uniform(0.0, 2.0 * math.pi)
        odo = WheelOdometry(robot, np.array([a0, a0]), np.zeros(3), slip_std=robot.odometry_noise,
                            rng=np.random.default_rng(rng.integers(2**63)))
        start_pose, start_weight = None, None
        for s in reads:
            a = a0 + omega * s * dt
            odo.update((a, a))
            if s == due[0] and start_pose is None:
                start_pose, start_weight = odo.pose, odo.slip_weight
        true = SPEED * (due[-1] - due[0]) * dt
        shift = odo.pose[:2] - start_pose[:2]
        errors.append(math.hypot(*shift) - true)
        n = len(reads) - 1
        claims.append(float(shift_var(robot, [true], 0.0, [n], [1.0], slip_weight=[odo.slip_weight - start_weight])[0]))
        equal.append(float(shift_var(robot, [true], 0.0, [n], [1.0])[0]))
    return np.array(errors), np.array(claims), np.array(equal)


def test_shift_variance_holds_for_a_fix_s_uneven_reads():
    base = scenarios.load("warehouse").robot
    robot = dataclasses.replace(base, encoder_ticks=2**24, odometry_noise=0.01, wheel_radius_error=0.0)
    lo, hi = stats.chi2.ppf([ALPHA / 2, 1 - ALPHA / 2], N)
    errors, claims, equal = _trials(robot, first_step=1)
    assert lo <= np.sum(errors**2 / claims) <= hi
    # negative control: n equal increments understate the slip of these uneven ones
    assert np.sum(errors**2 / equal) > hi
