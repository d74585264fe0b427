"""A fix taken while moving: earlier ranges carried to the fix time by odometry.

The laser measures a fix's k markers one after another, ``measurement_time`` apart, while the
robot drives on. A range ``r_i`` taken at ``p_i`` to marker ``M_i`` is, seen from the fix's end
position ``p_end``, a range to the *shifted* marker ``M_i + (p_end - p_i)``; the shift is
dead-reckoned, so each range's error band widens by a bound on the odometry error of its shift
(:func:`shift_bound`). The fault area of the fix is the intersection of the annuli
``| |p - M_i'| - r_i | <= rho_i + shift_bound_i``.

One construction serves both sides of the promise (`docs/design.md` §1):

- the simulation's **realised** fault area (``sim.episode.fixes``): measured ranges,
  dead-reckoned displacements turned into the world frame with the filter's heading after the
  fix's updates, and that heading's std (the snapshot estimate beside it turns them with the
  heading from before, whose error is independent of the fix's noise: :func:`shift_cov`);
- the planner's **predicted** fault area (:func:`promised_fault_area`, used by
  ``planner.schedule.schedule``): noise-free ranges at the planned poses, the planned displacements, and
  the heading std the plan assumes (``planning.heading_std_deg``).

A range taken at the fix time itself (the last one) has travelled 0 and is not widened.
"""

from __future__ import annotations

import math

import numpy as np

from estimators.encoder_phase import count_error_var
from estimators.fault.annuli import _OK, _region
from estimators.fault.exact import DEFAULT_TOLERANCE_FRACTION, FaultArea, _input_summary, exact_fault_area
from jit import compiled
from scenarios.schema import RobotSpec, SensorSpec

K_SIGMA = 3.0
"""Multiple of a random error's std taken as its bound in :func:`shift_bound` (99.73 %)."""


def encoder_tick(robot: RobotSpec) -> float:
    """Wheel travel per encoder tick ``2 pi r / ticks`` [m]."""
    return 2.0 * math.pi * robot.wheel_radius / robot.encoder_ticks


def shift_bound(robot: RobotSpec, travelled, heading_std: float) -> np.ndarray:
    """Bound on the odometry error of a dead-reckoned shift over ``travelled`` metres [m].

    Each wheel's travel between two encoder readings is off by less than one tick (both
    readings are floors of the true angle): along the track less than ``tick``, and the heading
    by less than ``2 tick / b``, which turns the rest of the shift. Add the declared random slip
    and the heading error the shift is turned with (as ``K_SIGMA`` bounds), and the systematic
    wheel error, over the distance. Only the fix's last range, taken at the fix time, is not
    shifted (its callers give it no margin); an earlier range whose encoders did not change
    still has its bound, as the wheels may have turned by less than a tick and the robot crept
    (an episode's standstill fix on the dock showed it: one truth outside its area in 40,800).

    The bound keeps a second tick (``2 tick`` along the track): the ``K_SIGMA`` parts are not
    hard bounds (a 3-sigma heading error is exceeded at 0.27 % of fixes) and the physics
    creeps a little beyond the declared model in turns (tens of micrometres over a fix). With
    one tick, 200 warehouse episodes had one truth outside its fault area in 40,800 fixes.

    Parameters
    ----------
    robot : RobotSpec
        The declared robot (``wheel_radius``, ``encoder_ticks``, ``odometry_noise``,
        ``wheel_radius_error``).
    travelled : array_like, shape (k,)
        Length of each shift [m], >= 0.
    heading_std : float
        Standard deviation of the heading the shift is turned with [rad].

    Returns
    -------
    numpy.ndarray, shape (k,)
        Bound [m].
    """
    tick, per_metre = _shift_coefficients(robot, heading_std)
    if np.size(travelled) > 8:  # the schedule's candidate fixes, all at once
        d = np.asarray(travelled, dtype=float)
        return 2.0 * tick + per_metre * np.maximum(d, 0.0)
    # a fix has a few ranges: plain floats (numpy's per-call cost would dominate an episode's fixes)
    out = [2.0 * tick + per_metre * max(d, 0.0) for d in np.ravel(travelled).tolist()]
    return np.array(out).reshape(np.shape(travelled))


def _shift_coefficients(robot: RobotSpec, heading_std: float) -> tuple[float, float]:
    """``tick`` [m] and ``per_metre`` [m/m] of :func:`shift_bound` (``2 tick + per_metre d``)."""
    tick = encoder_tick(robot)
    per_metre = (K_SIGMA * robot.odometry_noise + abs(robot.wheel_radius_error) + K_SIGMA * max(heading_std, 0.0)
                 + 2.0 * tick / robot.wheel_base)
    return tick, per_metre


def turn_bound(robot: RobotSpec, travelled, turned, reads=None, wheel_paths=None, bounded: bool = False) -> np.ndarray:
    """Bound on the odometry error of a dead-reckoned heading change [rad].

    A bearing taken earlier in a fix is turned into the frame of the last one by the
    odometry's heading change ``turned`` since; its error is ``(e_right - e_left) / b`` with
    ``e_w`` each wheel's travel error. Per wheel: less than one tick of quantisation (both
    readings are floors), the declared systematic radius error ``|wheel_radius_error|`` times
    the wheel's true travel (at most its reported travel ``|d_w|`` plus a tick), and the random
    slip of std ``odometry_noise |increment|`` per read. The wheels' travels are
    ``d_w = s +- b turned / 2`` over the midpoint's path ``s``, taken as the arc of chord
    ``travelled`` and turn ``turned`` (constant curvature over the shift).

    The slip's part:

    - ``bounded`` (a bounded-noise world: each read's slip is within ``sqrt(3) odometry_noise
      |increment|``): a hard bound, ``sqrt(3) odometry_noise`` times the two wheels' summed
      ``|increment|`` over the reads (``wheel_paths``, or ``|d_l| + |d_r|`` of the arc). The
      ``K_SIGMA`` form below missed a 4.1-sigma normal slip of the simulation on random-23-037
      (one truth outside its fault area in 12,600 fixes), which is why a bounded world's
      floor now slips within a bound too.
    - otherwise ``K_SIGMA`` times the std of the sum over ``reads`` equal increments, like
      :func:`shift_bound`'s.

    Parameters
    ----------
    robot : RobotSpec
        The declared robot.
    travelled : array_like, shape (k,)
        Length of each dead-reckoned shift (its chord) [m], >= 0.
    turned : array_like, shape (k,)
        Dead-reckoned heading change over each shift [rad].
    reads : array_like, shape (k,), optional
        Odometry reads over each shift; by default one (the slip of one increment, an upper
        bound). Not used when ``bounded``.
    wheel_paths : array_like, shape (k, 2), optional
        Each wheel's summed ``|increment|`` over each shift's reads (left, right) [m]
        (:attr:`sim.physics.odometry.WheelOdometry.wheel_paths`' increase); with ``bounded``
        only, by default the arc's ``|d_l|`` and ``|d_r|``.
    bounded : bool
        The slip is bounded (uniform in ``+-sqrt(3) odometry_noise |increment|``).

    Returns
    -------
    numpy.ndarray, shape (k,)
        Bound [rad].
    """
    d = np.ravel(travelled).tolist()
    dth = np.ravel(turned).tolist()
    n = [1.0] * len(d) if reads is None else np.ravel(reads).tolist()
    paths = None if wheel_paths is None else np.reshape(wheel_paths, (-1, 2)).tolist()
    b, tick = robot.wheel_base, encoder_tick(robot)
    out = []
    for j, (dj, tj, nj) in enumerate(zip(d, dth, n, strict=True)):  # a fix has a few bearings: plain floats
        h = 0.5 * abs(tj)
        path = max(dj, 0.0) * (h / math.sin(h) if 0.0 < h < 0.5 * math.pi else 1.0)
        x = 0.5 * b * abs(tj)                  # the wheels' travels are path +- x
        if bounded:
            rolled = (abs(path - x) + abs(path + x)) if paths is None else paths[j][0] + paths[j][1]
            slip = math.sqrt(3.0) * robot.odometry_noise * rolled
        else:
            slip = K_SIGMA * robot.odometry_noise * math.sqrt((2.0 * path * path + 2.0 * x * x) / max(nj, 1.0))
        e = abs(robot.wheel_radius_error)
        out.append((2.0 * tick * (1.0 + e) + e * 2.0 * max(path, x) + slip) / b)
    return np.array(out).reshape(np.shape(travelled))


def shift_var(robot: RobotSpec, travelled, heading_var: float, reads=None, along_cos=None,
              slip_weight=None, count_var=None) -> np.ndarray:
    """Variance of each range's error from the odometry error of its shift [m^2].

    Along the shift: the two encoder readings' quantisation (the shift's error is the
    difference of two residuals, ``tick^2 / 12`` for the wheels' mean; none when both ends are
    the same reading) and the random slip, drawn per odometry read on each wheel with std
    ``odometry_noise |d_w|`` for that read's travel ``d_w``: the wheels' mean travel has slip
    variance ``odometry_noise^2 sum (d_l^2 + d_r^2) / 4`` over the reads (``slip_weight``), which
    is ``odometry_noise^2 d^2 / (2 n)`` for ``n`` equal increments and more for unequal ones (a
    fix's measurement reads fall between the control ticks; on the random world random-7-008
    the equal-increment form understated the first range's shift error, 150 against 141 um rms
    along the shift, one cause of its snapshot coverage 0.9427). Across it: the heading
    uncertainty turning the shift. The wheel-radius error is left out: to first order the
    wheels' mean travel does not see it. Each part is projected on the range's direction.

    Parameters
    ----------
    robot : RobotSpec
        The declared robot.
    travelled : array_like, shape (k,)
        Length of each shift [m], >= 0.
    heading_var : float
        Variance of the heading the shift is turned with [rad^2].
    reads : array_like, shape (k,), optional
        Odometry reads over each shift; by default one (the slip of one increment).
    along_cos : array_like, shape (k,), optional
        Cosine between each shift and its range's direction; by default 1 for the along part
        and 1 for the across part (an upper bound).
    slip_weight : array_like, shape (k,), optional
        ``sum (d_l^2 + d_r^2) / 4`` over the odometry reads of each shift [m^2]
        (:attr:`sim.physics.odometry.WheelOdometry.slip_weight`'s increase); by default the
        equal-increment value ``d^2 / (2 n)``.
    count_var : array_like, shape (k, 2), optional
        Each wheel's count-error variance over each shift [m^2]
        (:func:`estimators.encoder_phase.count_error_var` of the turn the command predicts: a
        fix's shifts are coherent across runs); by default that of two independent residuals,
        ``tick^2 / 6`` (the wheels' mean then has the ``tick^2 / 12`` above).

    Returns
    -------
    numpy.ndarray, shape (k,)
        Variance [m^2]; 0 for a shift of exactly 0.
    """
    d = np.ravel(travelled).tolist()
    n = [1.0] * len(d) if reads is None else np.ravel(reads).tolist()
    cos = None if along_cos is None else np.ravel(along_cos).tolist()
    weight = None if slip_weight is None else np.ravel(slip_weight).tolist()
    slip2, hv = robot.odometry_noise**2, max(heading_var, 0.0)
    quant = ([encoder_tick(robot) ** 2 / 12.0] * len(d) if count_var is None
             else (0.25 * np.asarray(count_var, dtype=float).reshape(len(d), 2).sum(axis=1)).tolist())
    out = []
    for j, dj in enumerate(d):  # a fix has a few ranges: plain floats
        if dj <= 0.0:
            out.append(0.0)
            continue
        slip_part = dj * dj / (2.0 * max(n[j], 1.0)) if weight is None else max(weight[j], 0.0)
        along = (quant[j] if n[j] > 0 else 0.0) + slip2 * slip_part
        across = hv * dj * dj
        c2 = 1.0 if cos is None else cos[j] * cos[j]
        out.append(along + across if cos is None else along * c2 + across * (1.0 - c2))
    return np.array(out).reshape(np.shape(travelled))


def shift_cov(robot: RobotSpec, travelled, heading_var: float, reads=None, along_cos=None, across=None,
              slip_weight=None, count_cov=None) -> np.ndarray:
    """Covariance of the ranges' errors from the odometry errors of their shifts [m^2].

    The diagonal is :func:`shift_var`. The shifts of one fix are not independent: all end at the
    same odometry read and each later one is part of every earlier one, so two carried ranges
    share the end read's quantisation residual (``tick^2 / 24`` for the wheels' mean, half of
    :func:`shift_var`'s two residuals) and the slip of the reads the shorter shift spans, both
    along the shifts; and all are turned into the world frame with the same heading, whose
    error ``e`` moves range ``i`` by ``e a_i`` with ``a_i = s_i x u_i`` (the shift's component
    across the range, signed). Left out, the shared parts made the snapshot covariance of the
    random world random-7-008 too small at speed (+0.02 on the mean of ``d^T C^-1 d``
    over its fixes, +0.04 at 0.8 m/s and more). The off-diagonal terms use the same
    projections as the diagonal: each shift's own ``along_cos`` (nearly the same direction
    for all within a fix).

    Parameters
    ----------
    robot : RobotSpec
        The declared robot.
    travelled : array_like, shape (k,)
        Length of each shift [m], >= 0 (0: a range not carried).
    heading_var : float
        Variance of the heading the shifts are turned with [rad^2].
    reads : array_like, shape (k,), optional
        Odometry reads over each shift; by default one.
    along_cos : array_like, shape (k,), optional
        Cosine between each shift and its range's direction; by default 1 (the diagonal's
        upper bound of :func:`shift_var`; the off-diagonal along parts then count fully).
    across : array_like, shape (k,), optional
        Signed component of each shift across its range's direction ``s_i x u_i`` [m]; by
        default no heading term off the diagonal.
    slip_weight : array_like, shape (k,), optional
        As in :func:`shift_var`.
    count_cov : array_like, shape (k, k, 2), optional
        Each wheel's covariance of the shifts' count errors [m^2] (:func:`count_cov`); by
        default independent residuals: ``tick^2 / 6`` on the diagonal, the shared end reading's
        ``tick^2 / 12`` off it.

    Returns
    -------
    numpy.ndarray, shape (k, k)
        Covariance [m^2]; rows and columns of a range not carried are 0.
    """
    cc = None if count_cov is None else np.asarray(count_cov, dtype=float)
    var = shift_var(robot, travelled, heading_var, reads, along_cos, slip_weight,
                    None if cc is None else np.diagonal(cc).T)
    d = np.ravel(travelled).tolist()
    k = len(d)
    n = [1.0] * k if reads is None else np.ravel(reads).tolist()
    cos = [1.0] * k if along_cos is None else np.ravel(along_cos).tolist()
    a = None if across is None else np.ravel(across).tolist()
    weight = None if slip_weight is None else np.ravel(slip_weight).tolist()
    end_quant, slip2, hv = encoder_tick(robot) ** 2 / 24.0, robot.odometry_noise**2, max(heading_var, 0.0)
    slip_part = [0.0 if dj <= 0.0 else (dj * dj / (2.0 * max(n[j], 1.0)) if weight is None else max(weight[j], 0.0))
                 for j, dj in enumerate(d)]
    out = np.diag(np.ravel(var))
    for i in range(k):  # a fix has a few ranges: plain floats
        for j in range(i + 1, k):
            if d[i] <= 0.0 or d[j] <= 0.0:
                continue
            shared = end_quant if cc is None else 0.25 * (cc[i, j, 0] + cc[i, j, 1])
            quant = shared if n[i] > 0 and n[j] > 0 else 0.0
            c = (quant + slip2 * min(slip_part[i], slip_part[j])) * cos[i] * cos[j]
            if a is not None:
                c += hv * a[i] * a[j]
            out[i, j] = out[j, i] = c
    return out


def turn_cov(robot: RobotSpec, travelled, turned, reads=None, slip_weight=None, count_cov=None) -> np.ndarray:
    """Covariance of the dead-reckoned turns that carry a fix's bearings to its last one [rad^2].

    A bearing taken earlier in a fix is turned into the last one's frame by the odometry's
    heading change since (``sim.episode.fixes``); that change is off by ``(e_r - e_l) / b``, with
    ``e_w`` each wheel's travel error over the shift (:func:`turn_bound` bounds it). Its parts,
    as random errors:

    - quantisation: each wheel's reported travel is off by the difference of two reading
      residuals, independent and uniform over a tick (``tick^2 / 12`` each), so the turn's
      variance is ``4 tick^2 / (12 b^2)``; two carried bearings share the end reading's
      residuals, ``2 tick^2 / (12 b^2)``. None when both ends are the same reading.
    - random slip, drawn per read and wheel with std ``odometry_noise |d_w|``: variance
      ``odometry_noise^2 sum (d_l^2 + d_r^2) / b^2 = 4 odometry_noise^2 slip_weight / b^2``;
      nested shifts share the shorter one's reads.
    - the wheel-radius error ``e`` (right ``r (1 + e)``, left ``r (1 - e)``, sign unknown, taken
      with std ``|wheel_radius_error|`` as the filter's prior): ``2 e s / b`` over the midpoint's
      path ``s``, common to every bearing of the fix.

    Left out, a carried bearing's weight was that of its sensor noise alone: on the random
    world random-23-016 (536 ticks on 0.097 m wheels, bearings 0.16 deg gaussian) the
    quantisation's turn std, 1.1 mrad, exceeds the bearing's 0.93 mrad, and the snapshot's
    coverage was 0.8966 against 0.95 over 86,400 fixes.

    Parameters
    ----------
    robot : RobotSpec
        The declared robot.
    travelled : array_like, shape (k,)
        Length of each shift (its chord) [m], >= 0; 0 with ``reads`` 0: not carried.
    turned : array_like, shape (k,)
        Dead-reckoned heading change over each shift [rad].
    reads : array_like, shape (k,), optional
        Odometry reads over each shift; by default one.
    slip_weight : array_like, shape (k,), optional
        ``sum (d_l^2 + d_r^2) / 4`` over each shift's reads [m^2]
        (:attr:`sim.physics.odometry.WheelOdometry.slip_weight`'s increase); by default the
        equal-increment value over the arc's wheel travels, as in :func:`turn_bound`.
    count_cov : array_like, shape (k, k, 2), optional
        Each wheel's covariance of the shifts' count errors [m^2] (:func:`count_cov`); by
        default that of independent residuals (above).

    Returns
    -------
    numpy.ndarray, shape (k, k)
        Covariance [rad^2]; rows and columns of a bearing not carried are 0.
    """
    d = np.ravel(travelled).tolist()
    dth = np.ravel(turned).tolist()
    k = len(d)
    n = [1.0] * k if reads is None else np.ravel(reads).tolist()
    b, tick, e = robot.wheel_base, encoder_tick(robot), abs(robot.wheel_radius_error)
    quant, slip2 = tick * tick / (12.0 * b * b), robot.odometry_noise**2
    path, weight, moved = [], [], []
    for j in range(k):  # a fix has a few bearings: plain floats
        h = 0.5 * abs(dth[j])
        s = max(d[j], 0.0) * (h / math.sin(h) if 0.0 < h < 0.5 * math.pi else 1.0)
        x = 0.5 * b * abs(dth[j])
        path.append(s)
        moved.append(n[j] > 0 or s > 0.0)
        if slip_weight is None:
            weight.append((2.0 * s * s + 2.0 * x * x) / (4.0 * max(n[j], 1.0)))
        else:
            weight.append(max(float(np.ravel(slip_weight)[j]), 0.0))
    out = np.zeros((k, k))
    for i in range(k):
        if not moved[i]:
            continue
        for j in range(i, k):
            if not moved[j]:
                continue
            if count_cov is None:
                shared_quant = 4.0 * quant if i == j else 2.0 * quant
            else:
                shared_quant = (float(count_cov[i][j][0]) + float(count_cov[i][j][1])) / (b * b)
            c = shared_quant + 4.0 * slip2 * min(weight[i], weight[j]) / (b * b) \
                + (2.0 * e / b) ** 2 * path[i] * path[j]
            out[i, j] = out[j, i] = c
    return out


def count_cov(robot: RobotSpec, turns, steps, sigma_per_step) -> np.ndarray:
    """Each wheel's covariance of a fix's shifts' count errors, coherent across runs [m^2].

    Shift i runs from measurement i to the fix's end E; its count error is the difference of
    the residuals at its ends, so two shifts share ``cov = (V(i, E) + V(j, E) - V(i, j)) / 2``,
    ``V`` a window's count-error variance (:func:`estimators.encoder_phase.count_error_var`) for
    the turn the wheel command predicts between the two reads and its uncertainty. Across the
    runs of a sweep a fix's windows turn the wheels the same to ~0.005 ticks: the variance is
    that of their fractional turn, not the ``tick^2 / 6`` of independent residuals
    (``docs/design.md`` §6).

    Parameters
    ----------
    robot : RobotSpec
        The declared robot (its encoder tick).
    turns : array_like, shape (k + 1, 2)
        Each wheel's commanded turn [ticks] up to each measurement and to the fix's end (last
        row), from any origin.
    steps : array_like, shape (k + 1,)
        The physics step of each (any origin).
    sigma_per_step : array_like, shape (2,)
        Each wheel's turn uncertainty per physics step [ticks]
        (:func:`estimators.encoder_phase.sigma_per_step`; inf: unknown).

    Returns
    -------
    numpy.ndarray, shape (k, k, 2)
    """
    t = np.asarray(turns, dtype=float)
    st = np.asarray(steps, dtype=float)
    sig = np.asarray(sigma_per_step, dtype=float)
    # V between every two rows, per wheel: (k + 1, k + 1, 2); the same read: no window, no error
    dt = t[None, :, :] - t[:, None, :]
    span = np.abs(st[None, :] - st[:, None])[..., None]
    with np.errstate(invalid="ignore"):   # 0 steps times an unknown (inf) rate: no window
        ds = np.where(span == 0.0, 0.0, span * sig)
    V = np.where(span == 0.0, 0.0, count_error_var(dt, ds))
    end = V[:-1, -1, :]                                      # V(i, E)
    out = 0.5 * (end[:, None, :] + end[None, :, :] - V[:-1, :-1, :])
    return out * encoder_tick(robot) ** 2


def carry(markers, at, end, rotation: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Shift each marker by the displacement from where its range was taken to the fix's end.

    Parameters
    ----------
    markers : array_like, shape (k, 2)
        Positions of the measured markers [m], in measurement order.
    at : array_like, shape (k, 2)
        Position at each measurement in the displacement's frame (dead reckoning, or the
        world for a plan) [m].
    end : array_like, shape (2,)
        Position at the fix's end, same frame [m].
    rotation : float
        Angle from the displacement's frame to the world frame [rad] (0 for a plan).

    Returns
    -------
    shifted : numpy.ndarray, shape (k, 2)
        ``M_i + R(rotation) (end - at_i)`` [m].
    travelled : numpy.ndarray, shape (k,)
        ``|end - at_i|`` [m].
    """
    m = np.asarray(markers, dtype=float).reshape(-1, 2).tolist()
    a = np.asarray(at, dtype=float).reshape(-1, 2).tolist()
    ex, ey = float(end[0]), float(end[1])
    c, s = math.cos(rotation), math.sin(rotation)
    shifted, travelled = [], []
    for (mx, my), (ax, ay) in zip(m, a, strict=True):  # a fix has a few ranges: plain floats
        dx, dy = ex - ax, ey - ay
        shifted.append((mx + c * dx - s * dy, my + s * dx + c * dy))
        travelled.append(math.hypot(dx, dy))
    return np.array(shifted).reshape(-1, 2), np.array(travelled)


def promised_fault_area(sensor: SensorSpec, robot: RobotSpec, markers, poses, heading_std: float,
                        end=None, carried=None) -> FaultArea:
    """Fault area of a moving fix from noise-free ranges at planned positions (the promise).

    The ranges ``|p_i - M_i|`` are exact; each is carried to the last position (:func:`carry`)
    and its band ``rho(r_i)`` widened by :func:`shift_bound`, exactly as the simulation builds a
    realised fault area from measured ranges. Bearings are not part of the promise.

    Parameters
    ----------
    sensor : SensorSpec
        The declared sensor (range bound ``Re r + rho0``).
    robot : RobotSpec
        The declared robot (odometry bound).
    markers : array_like, shape (k, 2)
        The fix's markers in measurement order [m].
    poses : array_like, shape (k, 2)
        Planned position at each measurement [m]; the last is the fix's position.
    heading_std : float
        Heading std the plan assumes at the fix [rad].
    end : array_like, shape (2,), optional
        The fix's position, where the ranges are carried to; default the last pose.
    carried : array_like of bool, shape (k,), optional
        Which ranges are carried (get the shift bound); default all but the last.

    Returns
    -------
    FaultArea
        The component at the fix's position; its ``diameter`` is the fix's ``predicted_tau``.
    """
    m = np.asarray(markers, dtype=float).reshape(-1, 2)
    p = np.asarray(poses, dtype=float).reshape(-1, 2)
    end = p[-1] if end is None else np.asarray(end, dtype=float)
    carried = np.arange(len(p)) < len(p) - 1 if carried is None else np.asarray(carried, dtype=bool)
    ranges = np.hypot(p[:, 0] - m[:, 0], p[:, 1] - m[:, 1])
    shifted, travelled = carry(m, p, end)
    rho = sensor.range_bound(ranges) + np.where(carried, shift_bound(robot, travelled, heading_std), 0.0)
    return exact_fault_area(shifted, ranges, rho, end)


def promised_diameters(sensor: SensorSpec, robot: RobotSpec, markers, poses,
                       heading_std: float) -> tuple[np.ndarray, np.ndarray]:
    """``promised_fault_area(...)``'s diameter and emptiness for many fixes.

    The same construction and the same floating-point operations as :func:`promised_fault_area`
    with the default ``end`` and ``carried``, prepared for all fixes at once (the schedule's
    chosen fixes: per-fix numpy calls on arrays of two cost more than the fault areas).

    Parameters
    ----------
    sensor, robot, heading_std
        As in :func:`promised_fault_area`.
    markers : array_like, shape (F, k, 2)
        Each fix's markers in measurement order [m].
    poses : array_like, shape (F, k, 2)
        Planned position at each measurement of each fix [m]; the last is the fix's position.

    Returns
    -------
    diameter : numpy.ndarray, shape (F,)
        Fault-area diameter [m] (nan where empty).
    empty : numpy.ndarray of bool, shape (F,)
        No position is consistent with the fix's ranges.
    """
    m = np.asarray(markers, dtype=float)
    p = np.asarray(poses, dtype=float)
    if m.ndim != 3 or m.shape[-1] != 2 or p.shape != m.shape:
        raise ValueError(f"promised_diameters: markers {m.shape} and poses {p.shape} must both be (F, k, 2)")
    diameter, empty = np.full(m.shape[0], np.nan), np.ones(m.shape[0], dtype=bool)
    if m.shape[0] == 0 or m.shape[1] == 0:
        return diameter, empty
    ranges = np.hypot(p[..., 0] - m[..., 0], p[..., 1] - m[..., 1])
    # carry() with rotation 0: M + 1.0 (end - at) - 0.0 (...), and math.hypot for the travel
    dx, dy = p[:, -1:, 0] - p[..., 0], p[:, -1:, 1] - p[..., 1]
    shifted = np.stack([m[..., 0] + 1.0 * dx - 0.0 * dy, m[..., 1] + 0.0 * dx + 1.0 * dy], axis=-1)
    travelled = np.array([math.hypot(a, b) for a, b in zip(dx.ravel().tolist(), dy.ravel().tolist(), strict=True)])
    tick, per_metre = _shift_coefficients(robot, heading_std)
    bound = 2.0 * tick + per_metre * np.maximum(travelled.reshape(dx.shape), 0.0)
    carried = np.arange(m.shape[1]) < m.shape[1] - 1
    rho = sensor.range_bound(ranges) + np.where(carried[None, :], bound, 0.0)
    prior = np.ascontiguousarray(p[:, -1])
    status = np.full(m.shape[0], -1, dtype=np.int64)
    if m.shape[1] == 2:  # exact_fault_area's closed form, without its per-fix Python and numpy calls
        _two_range_diameters(np.ascontiguousarray(shifted), ranges, rho, prior, status, diameter)
    fast = status == _OK
    empty[fast] = False
    for i in np.flatnonzero(~fast).tolist():  # the rest as exact_fault_area finds them (or raises)
        area = exact_fault_area(shifted[i], ranges[i], rho[i], prior[i])
        diameter[i], empty[i] = area.diameter, area.is_empty
    return diameter, empty


@compiled.njit(cache=True, nogil=True)
def _two_range_diameters(markers, ranges, rho, prior, status, diameter):
    """Diameter of exact_fault_area's closed form (default tolerance) for each two-range fix.

    ``status[i]`` is the closed form's (0: applies), or -1 where the inputs are not finite, a
    rho is not > 0, or a range plus its rho is negative: exact_fault_area decides those rows.
    """
    for i in range(markers.shape[0]):
        total, rho_min, reach_min = _input_summary(markers[i], ranges[i], rho[i])
        if not (math.isfinite(total) and rho_min > 0.0 and reach_min >= 0.0):
            continue
        code, _, _, _, _, d = _region(markers[i], ranges[i], rho[i], prior[i],
                                      DEFAULT_TOLERANCE_FRACTION * rho_min, np.bool_(False))
        status[i] = code
        diameter[i] = d


def promised_parallelogram(sensor: SensorSpec, robot: RobotSpec, markers, poses, heading_std: float) -> np.ndarray:
    """Linearised diameter of two-marker moving fixes, vectorised (the schedule's search model).

    The parallelogram of :func:`promised_fault_area`'s construction: unit vectors from each
    marker to where it was measured (a shift keeps the direction from the shifted marker to
    the end), half-widths ``rho(r_i) + shift_bound_i``, diagonal of paper eq. 12.

    Parameters
    ----------
    sensor, robot, heading_std
        As in :func:`promised_fault_area`.
    markers : array_like, shape (..., 2, 2)
        The two markers of each fix, in measurement order [m].
    poses : array_like, shape (..., 2, 2)
        Planned position at each of the two measurements [m].

    Returns
    -------
    numpy.ndarray, shape (...)
        Diameter [m]; inf where the geometry is degenerate.
    """
    m = np.asarray(markers, dtype=float)
    p = np.asarray(poses, dtype=float)
    d = p - m
    r = np.hypot(d[..., 0], d[..., 1])
    u = d / np.where(r > 0, r, 1.0)[..., None]
    dd = p[..., 1, :] - p[..., 0, :]
    travelled = np.hypot(dd[..., 0], dd[..., 1])
    rho0 = sensor.range_bound(r[..., 0]) + shift_bound(robot, travelled, heading_std)
    rho1 = sensor.range_bound(r[..., 1])
    sin_a = np.abs(u[..., 0, 0] * u[..., 1, 1] - u[..., 0, 1] * u[..., 1, 0])
    cos_a = np.abs(u[..., 0, 0] * u[..., 1, 0] + u[..., 0, 1] * u[..., 1, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        diag = 2.0 / sin_a * np.sqrt(rho0 * rho0 + rho1 * rho1 + 2.0 * rho0 * rho1 * cos_a)
    return np.where((sin_a > 1e-12) & (r.min(axis=-1) > 0), diag, np.inf)


@compiled.njit(cache=True, inline="always")
def _diagonal(ax, ay, bx, by, p0x, p0y, p1x, p1y, rel, ab, sb):
    """:func:`promised_parallelogram` of one fix: marker a measured at p0 (carried), b at p1."""
    d0x, d0y, d1x, d1y = p0x - ax, p0y - ay, p1x - bx, p1y - by
    r0, r1 = math.hypot(d0x, d0y), math.hypot(d1x, d1y)
    q0 = r0 if r0 > 0 else 1.0
    q1 = r1 if r1 > 0 else 1.0
    u0x, u0y, u1x, u1y = d0x / q0, d0y / q0, d1x / q1, d1y / q1
    rho0 = (rel * r0 + ab) + sb
    rho1 = rel * r1 + ab
    sin_a = abs(u0x * u1y - u0y * u1x)
    cos_a = abs(u0x * u1x + u0y * u1y)
    if not (sin_a > 1e-12 and min(r0, r1) > 0):
        return np.inf
    return 2.0 / sin_a * math.sqrt(rho0 * rho0 + rho1 * rho1 + 2.0 * rho0 * rho1 * cos_a)


@compiled.njit(cache=True, nogil=True)
def _best_order(mk, sub, p, c, j, rel, ab, tick, per_metre, tau, flip):
    for i in range(c.size):
        a, b = sub[c[i], 0], sub[c[i], 1]
        fwd, rev = -np.inf, -np.inf
        for lag in range(p.shape[0]):
            q = p[lag, j[i]]
            p0x, p0y, p1x, p1y = q[0, 0], q[0, 1], q[1, 0], q[1, 1]
            sb = 2.0 * tick + per_metre * max(math.hypot(p1x - p0x, p1y - p0y), 0.0)
            fwd = max(fwd, _diagonal(mk[a, 0], mk[a, 1], mk[b, 0], mk[b, 1], p0x, p0y, p1x, p1y, rel, ab, sb))
            rev = max(rev, _diagonal(mk[b, 0], mk[b, 1], mk[a, 0], mk[a, 1], p0x, p0y, p1x, p1y, rel, ab, sb))
        tau[i] = rev if rev < fwd else fwd
        flip[i] = rev < fwd


def promised_parallelogram_best(sensor: SensorSpec, robot: RobotSpec, markers, pairs, poses, c, j,
                                heading_std: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`promised_parallelogram` in the better of the two measurement orders, for many fixes.

    The same arithmetic, one fix at a time (compiled): the schedule scores a hundred thousand
    candidate fixes per speed level.

    Parameters
    ----------
    sensor, robot, heading_std
        As in :func:`promised_fault_area`.
    markers : array_like, shape (M, 2)
        Marker positions [m].
    pairs : array_like of int, shape (C, 2)
        Marker pairs, in their forward measurement order.
    poses : array_like, shape (n, 2, 2) or (L, n, 2, 2)
        Planned position at each of the two measurements of a fix started at each sample [m];
        with L sets (e.g. starts at several lags) each order's diameter is its largest over them.
    c, j : array_like of int, shape (K,)
        The fixes: pair ``pairs[c]`` started at sample ``j``.

    Returns
    -------
    tau : numpy.ndarray, shape (K,)
        Diameter of the better order [m] (each order at its worst pose set); inf where the
        geometry is degenerate.
    flipped : numpy.ndarray of bool, shape (K,)
        The reversed order is strictly better.
    """
    c = np.ascontiguousarray(c, dtype=np.int64)
    j = np.ascontiguousarray(j, dtype=np.int64)
    tau, flip = np.empty(c.size), np.empty(c.size, dtype=np.bool_)
    tick, per_metre = _shift_coefficients(robot, heading_std)
    p = np.asarray(poses, dtype=float)
    p = p[None] if p.ndim == 3 else p
    _best_order(np.ascontiguousarray(markers, dtype=float), np.ascontiguousarray(pairs, dtype=np.int64),
                np.ascontiguousarray(p), c, j, float(sensor.relative_error),
                float(sensor.absolute_error), float(tick), float(per_metre), tau, flip)
    return tau, flip


compiled.keep_fresh(__name__)
