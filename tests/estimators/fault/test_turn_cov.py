"""The snapshot's carried-turn covariance against the simulated odometry, with coarse encoders.

A bearing taken earlier in a fix is turned into the last measurement's frame by the
dead-reckoned heading change since (``sim.episode.fixes``); :func:`estimators.fault.carried.turn_cov`
gives the covariance of those turns' errors, ``(e_r - e_l) / b`` with ``e_w`` each wheel's travel
error: quantisation (each wheel's reported travel is off by the difference of two reading
residuals, uniform over a tick: ``4 tick^2 / (12 b^2)``), random slip per odometry read
(``4 odometry_noise^2 slip_weight / b^2``) and the wheel-radius error. Two carried bearings of
one fix share the end reading's residuals (``2 tick^2 / (12 b^2)``) and the slip of the reads
the shorter shift spans. Left out, the random world ``random-23-016`` (536 ticks on 0.097 m
wheels, wheel base 0.59 m: a 1.1 mrad turn std from quantisation alone, above its bearings'
0.93 mrad) had snapshot coverage 0.8966; with it, 0.946.

Here the odometry (:class:`sim.physics.odometry.WheelOdometry`) reads the wheels of that robot
(the warehouse robot with ``random-23-016``'s encoders and geometry, ``odometry_noise`` 0.01,
no radius error: that one is a fixed unknown, not random per trial) with the episode's pattern:
control reads every ``CONTROL_STEPS`` physics steps and a fix's ``k = 3`` measurement reads,
``MEASUREMENT_TIME`` apart (``random-23-016``'s), at the physics steps they fall due. The wheels
roll on a curve, the robot at about 0.5 m/s turning at about 0.5 rad/s, each wheel's start angle
uniform per trial and independent of the other's. The error of the dead-reckoned turn from the
first (and the second) measurement read to the last is compared with the true one,
``(right travel - left travel) / b`` at the nominal radius.

Each wheel's speed is drawn per trial too, uniform over a band of one tick per ``g`` physics
steps (``g`` the gcd of the gaps between the fix's measurement reads; 4 here: 0.068 m/s). With
fixed speeds the end reading's residual is the start's plus a fixed travel: a wheel's
quantisation error over the shift is two-valued with variance ``f (1 - f) tick^2`` for ``f`` the
fractional ticks of its travel, ``tick^2 / 6`` only on average over ``f``; at exactly 0.5 m/s
and 0.5 rad/s the first shift's wheels travel 18.98 and 10.33 ticks, ``f (1 - f)`` 0.018 and
0.222 against 1/6 each, and the statistic below measured 0.73 N (below the interval: such
trials do not follow the claim's model of independent residuals). Over the band, the fractional travels
between any two of the fix's three reads are uniform, so each pair of their residuals is
independent: the claim's second moments hold exactly.

The quantisation dominates (96 % of the claimed variance), so the errors are not gaussian but
platykurtic: ``z^2`` has variance about 1.7 (1.7 to 1.9 measured) rather than chi2's 2. The
acceptance region is the chi2(N) two-sided interval at false-alarm probability ``ALPHA``, then
conservative (its ends are 3.3 chi2 standard deviations from ``N``, about 3.4 of the statistic's).

Negative controls, each of which must be rejected (its statistic above the interval):

- the first turn's variance without the quantisation (the claim less ``4 tick^2 / (12 b^2)``,
  the slip part alone) is 1 / 23.7 of the claim, so its statistic is about ``23.7 chi2(N)``;
  with ``N = 2000`` the interval's upper end (1.107 N) is 30 standard deviations below its
  mean, and it passes with probability ``P(chi2(N) < 0.047 N) < exp(-N (a - 1 - ln a) / 2)``
  (``a = 0.047``) ``< 1e-900``;
- the sum of the two carried turns' errors with independent turns (``C_12 = 0``): it
  understates ``C_11 + C_22 + 2 C_12`` by the factor 1.505, so its statistic is about
  ``1.505 chi2(N)``, whose mean is 8.4 standard deviations above the interval's upper end:
  it passes with probability ``P(chi2(N) < 1.107 N / 1.505) = 1.4e-20``.

(Both with chi2's variance; the errors' smaller one makes a pass less likely still.) Measured
(seed below): 1.006 N for the first turn, 0.988 N for the sum, 23.8 N and 1.488 N for the
controls; 20,000 trials (another seed) gave 0.996 N and 0.997 N. The simulation takes about 2 s.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
from scipy import stats

import scenarios
from estimators.fault.carried import encoder_tick, turn_cov
from sim.physics.config import PhysicsConfig
from sim.physics.odometry import WheelOdometry
from tests.sim.episode.fix_reads import fix_reads

ALPHA = 0.001
N = 2000
SPEED = 0.5                # robot speed at the band's centre [m/s]
YAW_RATE = 0.5             # turn rate at the band's centre [rad/s]
MEASUREMENT_TIME = 0.015   # random-23-016's
K = 3                      # measurements per fix


def _robot():
    """Return the warehouse robot with random-23-016's coarse encoders and geometry."""
    base = scenarios.load("warehouse").robot
    return dataclasses.replace(base, encoder_ticks=536, wheel_radius=0.097, wheel_base=0.59,
                               odometry_noise=0.01, wheel_radius_error=0.0)


@functools.cache
def _trials(first_step: int = 1):
    """Dead-reckon N fixes' turns, from the first and from the second measurement read to the last.

    Returns the errors of the two carried turns, shape (N, 2), and each trial's claimed (2, 2)
    covariance of them, shape (N, 2, 2).
    """
    robot = _robot()
    b, r, tick = robot.wheel_base, robot.wheel_radius, encoder_tick(robot)
    dt = PhysicsConfig().time_step
    due, reads = fix_reads(first_step, K, MEASUREMENT_TIME, dt)
    # each wheel's speed band: a whole tick of travel between any two of the fix's reads
    band = tick / (math.gcd(*(t - s for i, s in enumerate(due) for t in due[i + 1:])) * dt)
    centre = np.array([SPEED - 0.5 * b * YAW_RATE, SPEED + 0.5 * b * YAW_RATE])   # left, right [m/s]
    rng = np.random.default_rng(20261223)
    errors, covs = np.zeros((N, 2)), np.zeros((N, 2, 2))
    for trial in range(N):
        speed = centre + band * rng.uniform(-0.5, 0.5, 2)
        a0 = rng.uniform(0.0, 2.0 * math.pi, 2)
        odo = WheelOdometry(robot, a0, np.zeros(3), slip_std=robot.odometry_noise,
                            rng=np.random.default_rng(rng.integers(2**63)))
        at = {}
        for j, s in enumerate(reads):
            odo.update(a0 + speed / r * (s * dt))
            if s in due and s not in at:
                at[s] = (odo.pose, odo.slip_weight, j)
        end = odo.pose
        starts = due[:2]
        true = [(speed[1] - speed[0]) * (due[-1] - s) * dt / b for s in starts]
        turned = [end[2] - at[s][0][2] for s in starts]
        chord = [math.hypot(*(end[:2] - at[s][0][:2])) for s in starts]
        n = [len(reads) - 1 - at[s][2] for s in starts]
        weight = [odo.slip_weight - at[s][1] for s in starts]
        errors[trial] = np.subtract(turned, true)
        covs[trial] = turn_cov(robot, chord, turned, n, weight)
    return errors, covs


def test_carried_turn_variance_holds_with_coarse_encoders():
    lo, hi = stats.chi2.ppf([ALPHA / 2, 1 - ALPHA / 2], N)
    errors, covs = _trials()
    robot = _robot()
    claim = covs[:, 0, 0]
    assert lo <= np.sum(errors[:, 0] ** 2 / claim) <= hi
    # negative control: the claim without the quantisation of the shift's two readings
    slip_only = claim - 4.0 * encoder_tick(robot) ** 2 / (12.0 * robot.wheel_base**2)
    assert np.all(slip_only > 0.0)
    assert np.sum(errors[:, 0] ** 2 / slip_only) > hi


def test_carried_turns_share_the_end_reading_and_slip():
    """The sum of a fix's two carried turn errors has the variance :func:`turn_cov` claims.

    The second bearing's shift is the end of the first's: their turns share the end reading's
    residuals and the slip of the second's reads, and ``e_1 + e_2`` has variance
    ``C_11 + C_22 + 2 C_12``; ``sum (e_1 + e_2)^2 / that`` over the trials is tested against
    chi2(N)'s two-sided interval at ``ALPHA``. Negative control: independent turns
    (``C_12 = 0``) understate it by the factor 1.505 (module docstring).
    """
    lo, hi = stats.chi2.ppf([ALPHA / 2, 1 - ALPHA / 2], N)
    errors, covs = _trials()
    total = errors[:, 0] + errors[:, 1]
    assert lo <= np.sum(total**2 / (covs[:, 0, 0] + covs[:, 1, 1] + 2.0 * covs[:, 0, 1])) <= hi
    assert np.sum(total**2 / (covs[:, 0, 0] + covs[:, 1, 1])) > hi
