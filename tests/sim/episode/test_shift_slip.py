"""The snapshot's carried-shift variance against the simulated odometry, for a fix's uneven reads.

A fix's ranges are carried to its last one by the dead-reckoned shift
(:mod:`estimators.fault.carried`); :func:`estimators.fault.carried.shift_var` gives the variance
of that shift's error, which the snapshot's covariance (and so the coverage check) includes.
The odometry draws its random slip per read, with std ``odometry_noise |d_w|`` for the read's
wheel travel ``d_w``; in an episode a fix's measurement reads fall between the control ticks
(``sim.episode.drive``), so the increments over a shift are unequal, and ``d^2 / (2 n)`` for
``n`` equal ones understates ``sum (d_l^2 + d_r^2) / 4``. That was the overconfidence of the
random world ``random-7-008`` (coverage 0.9427 of 46,397 fixes at 200 runs).

Here the odometry (:class:`sim.physics.odometry.WheelOdometry`) reads wheels rolling straight at
1 m/s with the episode's pattern (``tests/sim/episode/fix_reads.py``): control reads every
``CONTROL_STEPS`` physics steps and a fix's measurement reads at the physics steps they fall
due, once per step. Encoders of 2^24 ticks make the quantisation negligible (its
``tick^2 / 12`` is kept in the claim), so each trial's along-track shift error is gaussian with
the claimed variance and ``sum z^2`` over ``N`` independent trials is chi2(N): the acceptance
region is its two-sided interval at false-alarm probability ``ALPHA``. Negative control: the
equal-increment claim (``slip_weight`` not given) for the same reads lies outside it. A fix
starting a step before a control tick reads after 1, 4, 2, 2 and 4 steps: the equal claim is
1 / 1.213 of the exact one, so its statistic is ``1.213 chi2(N) / N`` and ``N = 4000`` puts the
interval's upper end (1.075 N) 5.1 standard deviations below its mean: the control misses with
probability 2e-7. (It measured 0.992 and 1.204. Before an episode read each physics step once,
a measurement on a tick read again, a zero increment, and the first trials' pattern gave 1.331.)
The same trials check the covariance of two nested shifts of a fix
(:func:`estimators.fault.carried.shift_cov`, the off-diagonal the snapshot covariance counts).
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
from scipy import stats

import scenarios
from estimators.fault.carried import shift_cov, shift_var
from sim.physics.config import PhysicsConfig
from tests.sim.episode.fix_reads import fix_reads

ALPHA = 0.001
N = 4000
FIRST_STEP = 3        # a fix starting a step before a control tick: its reads' increments 1, 4, 2, 2, 4 steps
SPEED = 1.0
MEASUREMENT_TIME = 0.027   # random-7-008's


def _robot():
    base = scenarios.load("warehouse").robot
    return dataclasses.replace(base, encoder_ticks=2**24, odometry_noise=0.01, wheel_radius_error=0.0)


@functools.cache
def _trials(first_step: int):
    """Dead-reckon N fixes' shifts, from the first and from the second measurement read to the last.

    Returns the errors of the first shifts, their claimed variance, the equal-increment claim,
    the errors of the second shifts, and each trial's claimed (2, 2) covariance of the two.
    """
    robot = _robot()
    from sim.physics.odometry import WheelOdometry

    dt = PhysicsConfig().time_step
    k = 3
    due, reads = fix_reads(first_step, k, MEASUREMENT_TIME, dt)
    rng = np.random.default_rng(20261203)
    omega = SPEED / robot.wheel_radius
    errors, claims, equal, errors2, covs = [], [], [], [], []
    for _ in range(N):
        a0 = rng.uniform(0.0, 2.0 * math.pi)
        odo = WheelOdometry(robot, np.array([a0, a0]), np.zeros(3), slip_std=robot.odometry_noise,
                            rng=np.random.default_rng(rng.integers(2**63)))
        at = {}
        for j, s in enumerate(reads):
            a = a0 + omega * s * dt
            odo.update((a, a))
            if s in due and s not in at:
                at[s] = (odo.pose, odo.slip_weight, j)
        true = [SPEED * (due[-1] - s) * dt for s in due[:2]]
        err = [math.hypot(*(odo.pose[:2] - at[s][0][:2])) - d for s, d in zip(due[:2], true, strict=True)]
        weight = [odo.slip_weight - at[s][1] for s in due[:2]]
        n = [len(reads) - 1 - at[s][2] for s in due[:2]]
        errors.append(err[0])
        errors2.append(err[1])
        claims.append(float(shift_var(robot, true[:1], 0.0, n[:1], [1.0], slip_weight=weight[:1])[0]))
        equal.append(float(shift_var(robot, true[:1], 0.0, n[:1], [1.0])[0]))
        covs.append(shift_cov(robot, true, 0.0, n, [1.0, 1.0], slip_weight=weight))
    return np.array(errors), np.array(claims), np.array(equal), np.array(errors2), np.array(covs)


def test_shift_variance_holds_for_a_fix_s_uneven_reads():
    lo, hi = stats.chi2.ppf([ALPHA / 2, 1 - ALPHA / 2], N)
    errors, claims, equal, _, _ = _trials(first_step=FIRST_STEP)
    assert lo <= np.sum(errors**2 / claims) <= hi
    # negative control: n equal increments understate the slip of these uneven ones
    assert np.sum(errors**2 / equal) > hi


def test_nested_shifts_share_their_slip():
    """The sum of a fix's two shift errors has the variance :func:`shift_cov` claims.

    The second range's shift is the end of the first's: they share its reads' slip, and
    ``e_1 + e_2`` has variance ``C_11 + C_22 + 2 C_12``; ``sum (e_1 + e_2)^2 / that`` over the
    trials is chi2(N), two-sided interval at ``ALPHA``. Negative control: independent shifts
    (``C_12 = 0``) understate it by the factor ``1 + 2 C_12 / (C_11 + C_22)``, 1.66 here, so
    the control's statistic ``1.66 chi2(N) / N`` misses the interval with probability < 1e-6
    (measured: 0.994 and 1.646).
    """
    lo, hi = stats.chi2.ppf([ALPHA / 2, 1 - ALPHA / 2], N)
    errors, _, _, errors2, covs = _trials(first_step=FIRST_STEP)
    total = errors + errors2
    assert lo <= np.sum(total**2 / (covs[:, 0, 0] + covs[:, 1, 1] + 2.0 * covs[:, 0, 1])) <= hi
    assert np.sum(total**2 / (covs[:, 0, 0] + covs[:, 1, 1])) > hi
