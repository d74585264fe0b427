"""One fix at a time: measure, update the EKF, judge the fix.

The chosen markers are measured one after another; each fix is judged against its own exact
fault area and the plan's promise for it.

The robot keeps moving while it measures (``measurement_time`` per marker), so a fix's ranges
are taken at different places. The snapshot fix brings them to the time of the last one with
the dead-reckoned displacement since each measurement: a range taken at p_i to marker M_i is a
range from p_end to the shifted marker M_i + (p_end - p_i), its band widened by the odometry
bound of the shift (:mod:`estimators.fault.carried`, the construction the planner's promise uses on
noise-free ranges at the planned poses). Each fix logs the promise (``predicted_tau``) and the
paper's static PEF of its subset at the truth (``static_tau``).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from estimators import encoder_phase
from estimators.encoder_phase import sigma_per_step
from estimators.fault.carried import (
    carry,
    count_cov,
    promised_fault_area,
    shift_bound,
    shift_cov,
    shift_var,
    turn_bound,
    turn_cov,
)
from estimators.snapshot import snapshot_fix
from scenarios import SimulationError
from scenarios.schema import NoiseModel
from sim.episode.types import FixLog


@dataclass
class _Pending:
    """A fix under way: markers still to measure and what has been measured so far."""

    markers: list[int]
    due: list[float]
    measured: list[int] = field(default_factory=list)
    ranges: list[float] = field(default_factory=list)
    bearings: list[float] = field(default_factory=list)
    dr_at: list[tuple[float, float, float]] = field(default_factory=list)
    reads_at: list[int | None] = field(default_factory=list)
    weight_at: list[float | None] = field(default_factory=list)
    paths_at: list[tuple[float, float] | None] = field(default_factory=list)
    # the filter's clock (physics steps) and each wheel's commanded turn [ticks] at each measurement
    phase_at: list[tuple[float, float, float]] = field(default_factory=list)
    # each wheel's commanded-turn uncertainty per physics step at the fix's end [ticks]
    phase_sigma: tuple[float, float] = (math.inf, math.inf)
    # the filter's heading, its variance and the dead-reckoned heading before the fix's first update
    heading0: tuple[float, float, float] | None = None
    nis: float = 0.0
    accepted: int = 0
    scheduled: object = None
    attempted: int = 0
    slots: list[int] = field(default_factory=list)
    fallback: int = -1   # the blocked slot whose fallback this fix measures, -1 for none
    beyond: bool = False
    unplanned: bool = False  # started on a subset the plan named neither as the fix's nor as its fallback
    note: object = None      # the caller's record of the fix (a fleet: the lines of sight robots blocked)


class FixRecorder:
    """Runs fixes during an episode and accumulates their :class:`FixLog`.

    Parameters
    ----------
    scenario : Scenario
    pef : planner.pef.map.PEF
        The declared-model PEF (predicts τ for a fix's subset at the true position).
    laser : sim.physics.laser.LaserSensor
        The simulated (actual) sensor.
    localizer : estimators.ekf.Localizer
    rng : numpy.random.Generator
        The sensor's noise stream.
    """

    def __init__(self, scenario, pef, laser, localizer, rng: np.random.Generator) -> None:
        self.scenario = scenario
        self.sensor = scenario.sensor  # declared: what the filter and the fault area assume
        self.robot = scenario.robot
        self.k = scenario.sensor.markers_per_fix
        self.markers = scenario.marker_positions()
        self.pef = pef
        self.laser = laser
        self.loc = localizer
        self.rng = rng
        self.pending: _Pending | None = None
        self.skipped = 0
        self.blocked_markers = 0
        self._fallback_next = -1
        self._beyond_next = False
        self._unplanned_next = False
        self._rows: list[dict] = []
        self._finished: list[tuple] = []  # fixes whose rows log() completes
        self._polygons: list[np.ndarray] = []

    # -- starting ------------------------------------------------------------------------

    def choose_subset(self, scheduled: tuple[int, ...], est_xy: np.ndarray, fix=None) -> list[int] | None:
        """Choose the markers of a fix.

        The scheduled subset if the laser sees all of it; else, when one of its markers is
        unseen and the schedule's fix (``fix``, a ``ScheduledFix``) names a fallback for it
        that the laser sees, that fallback (the fix is logged as a fallback fix); else the best
        visible subset by the PEF at the *estimated* position (the robot does not know the
        truth), logged as ``unplanned``; None if fewer than k markers are visible.
        """
        self._fallback_next, self._beyond_next, self._unplanned_next = -1, False, False
        if self.laser.sees_all(scheduled):  # the usual case: two rays, not M
            return list(scheduled)
        seen_sched = self.laser.visible_all(scheduled)
        fbs = getattr(fix, "fallbacks", ()) if fix is not None else ()
        if (~seen_sched).sum() == 1 and len(fbs) == len(scheduled):
            q = int(np.flatnonzero(~seen_sched)[0])
            alt = fbs[q]
            if alt and self.laser.visible_all(alt).all():
                self._fallback_next = q
                return list(alt)
        # improvising because lines of sight are blocked: more than the plan's redundancy covers
        self._beyond_next = bool(self.laser.blocked & set(scheduled))
        seen = np.flatnonzero(self.laser.visible_all())
        if len(seen) < self.k:
            return None
        best, best_tau = None, math.inf
        for sub in itertools.combinations(seen.tolist(), self.k):
            tau = float(self.pef.tau_subset(est_xy[None, :], np.array(sub))[0])
            if tau < best_tau:
                best, best_tau = list(sub), tau
        # a substitute: the plan named neither this subset for the fix nor a fallback of it
        self._unplanned_next = True
        return best if best is not None else list(seen[: self.k])

    def start(self, subset: list[int], t: float, scheduled=None, note=None) -> None:
        """Start a fix of ``subset`` (measured in that order) at time ``t`` [s].

        ``scheduled`` is the schedule's fix (``planner.schedule.schedule.ScheduledFix``) this one
        takes; its promise becomes the fix's ``predicted_tau``. ``note`` is kept with the fix's
        row (:attr:`FixLog.notes`).
        """
        mt = self.sensor.measurement_time
        self.pending = _Pending(markers=list(subset), due=[t + (j + 1) * mt for j in range(len(subset))],
                                scheduled=scheduled, fallback=self._fallback_next, beyond=self._beyond_next,
                                unplanned=self._unplanned_next, note=note)
        self._fallback_next, self._beyond_next, self._unplanned_next = -1, False, False

    @property
    def next_due(self) -> float:
        return self.pending.due[0] if self.pending else math.inf

    # -- measuring -----------------------------------------------------------------------

    def measure_due(self, dr_pose: np.ndarray, true_pose, t: float, reads: int | None = None,
                    slip_weight: float | None = None, wheel_paths: tuple[float, float] | None = None) -> None:
        """Take the measurement that is due now (the caller has predicted the EKF up to ``t``).

        ``true_pose`` is the robot's true pose now (x, y, theta), a tuple or an array.

        ``reads`` counts the odometry reads so far (any origin): the shifts' slip variance
        depends on how many increments they span (None: counted as one, an upper bound).
        ``slip_weight`` is the odometry's :attr:`~sim.physics.odometry.WheelOdometry.slip_weight`
        now: with it the slip variance of a shift is exact for reads of any spacing (None: the
        ``reads`` count, as if the increments were equal). ``wheel_paths`` are its
        :attr:`~sim.physics.odometry.WheelOdometry.wheel_paths` now: with them a bounded slip's
        turn error has a hard bound (None: taken from the shift's arc).
        """
        p = self.pending
        slot = p.attempted
        if p.heading0 is None:
            p.heading0 = (float(self.loc.x[2]), self.loc.heading_var, float(dr_pose[2]))
        p.attempted += 1
        i = p.markers.pop(0)
        p.due.pop(0)
        try:
            m = self.laser.measure(i, self.rng, true_pose)  # it checks the line of sight itself
        except SimulationError:
            m = None  # the marker went behind an obstacle during the fix
        if m is not None:
            res = self.loc.update_range(i, m.measured_range)
            p.nis += res.nis if res.accepted else 0.0
            p.accepted += int(res.accepted)
            if self.sensor.uses_bearing:
                # The declared model expects a bearing; hardware declared bearing-free in
                # [sensor.actual] (xi = 0) measures it without error.
                b = m.measured_bearing if m.measured_bearing is not None else m.true_bearing
                rb = self.loc.update_bearing(i, b)
                p.nis += rb.nis if rb.accepted else 0.0
                p.accepted += int(rb.accepted)
                p.bearings.append(b)
            p.measured.append(i)
            p.slots.append(slot)
            p.ranges.append(m.measured_range)
            p.dr_at.append(tuple(map(float, dr_pose)))  # floats: no numpy between physics steps
            p.reads_at.append(reads)
            p.weight_at.append(slip_weight)
            p.paths_at.append(wheel_paths)
            p.phase_at.append(self._phase_mark())
        if not p.markers:
            self._finish(dr_pose, true_pose, t, reads, slip_weight, wheel_paths)

    def _finish(self, dr_end: np.ndarray, true_pose, t: float, reads: int | None,
                slip_weight: float | None = None, wheel_paths: tuple[float, float] | None = None) -> None:
        p, self.pending = self.pending, None
        if len(p.measured) < 2:
            self.skipped += 1  # a marker vanished behind an obstacle mid-fix: no fix
            return
        # What the fix's snapshot and fault area need from now; they are computed in log(), after
        # the episode: between physics steps the interpreter runs from cold caches, and these
        # ~40 small numpy calls cost 3-4 times what they cost in one loop (a fifth of an
        # episode's non-physics time). Nothing in the episode reads them.
        p.phase_at.append(self._phase_mark())
        p.phase_sigma = sigma_per_step(self.loc.phase)
        self._finished.append((p, tuple(map(float, dr_end)), tuple(true_pose), t, reads, self.loc.x,
                               self.loc.heading_var, slip_weight, wheel_paths))

    def _phase_mark(self) -> tuple[float, float, float]:
        ph = self.loc.phase
        return float(ph[encoder_phase.NOW]), float(ph[encoder_phase.CMD_SUM_L]), float(ph[encoder_phase.CMD_SUM_R])

    def _complete(self, p: _Pending, dr_end: tuple, true_pose: tuple, t: float, reads: int | None,
                  x_est: np.ndarray, heading_var_now: float, slip_weight: float | None = None,
                  wheel_paths: tuple[float, float] | None = None) -> None:
        """Compute a finished fix's snapshot, fault area and promise, with the filter as it was then."""
        idx = np.array(p.measured)
        # Dead reckoning drifts in heading without bound; only its displacement over the fix is
        # trusted, turned into the world frame with a filter heading: two of them, for two uses.
        # - The snapshot (a least-squares estimate and its covariance) turns the shifts with the
        #   heading from before the fix's first update: the one after has been corrected with
        #   these same ranges, so its error is correlated with their noise, which the covariance
        #   cannot describe (on random-7-008 that made d^T C^-1 d 0.05 too large on average, 0.08
        #   at 0.8 m/s and more). Its error is common to every shift: shift_cov.
        # - The fault area (a set: truth inside when every error is within its bound) turns them
        #   with the heading after the updates, the tighter one: a bound needs no independence,
        #   and it is the heading std the plan's promise assumes (planning.heading_std_deg);
        #   the filter's std before a fix can exceed it where the fixes are sparse.
        # (A fix has a few measurements: plain floats, numpy's per-call cost would dominate.)
        heading0, heading_var0, dr_heading0 = p.heading0
        at = np.array([[float(d[0]), float(d[1])] for d in p.dr_at])
        end = (float(dr_end[0]), float(dr_end[1]))
        shifted, travelled = carry(self.markers[idx], at, end, heading0 - dr_heading0)
        area_markers, _ = carry(self.markers[idx], at, end, float(x_est[2]) - float(dr_end[2]))
        # each shift's direction against its range's (from the shifted marker to the estimate):
        # the cosine, and the shift's signed component across the range
        px, py = float(x_est[0]), float(x_est[1])
        along_cos, across = [], []
        for (sx, sy), (mx, my), d in zip(shifted.tolist(), self.markers[idx].tolist(), travelled.tolist(),
                                         strict=True):
            ux, uy = px - sx, py - sy
            norm = d * math.hypot(ux, uy)
            along_cos.append(((sx - mx) * ux + (sy - my) * uy) / norm if norm > 0.0 else 1.0)
            across.append(((sx - mx) * uy - (sy - my) * ux) * d / norm if norm > 0.0 else 0.0)
        reads_over = (None if reads is None or None in p.reads_at
                      else np.array([reads - at for at in p.reads_at], dtype=float))
        weight_over = (None if slip_weight is None or None in p.weight_at
                       else np.array([slip_weight - at for at in p.weight_at], dtype=float))
        paths_over = (None if wheel_paths is None or None in p.paths_at
                      else np.array([[wheel_paths[0] - at[0], wheel_paths[1] - at[1]] for at in p.paths_at]))
        ranges = np.array(p.ranges)
        rho = self.sensor.measured_range_bound(ranges)  # the declared bound holds at the true range
        # the count errors of the shifts: coherent across runs where the commanded turn is known
        # (a filter that does not count physics steps knows no turn: independent residuals)
        marks = np.array(p.phase_at)
        counts = (count_cov(self.robot, marks[:, 1:], marks[:, 0], p.phase_sigma)
                  if self.loc.phase[encoder_phase.STEP_TIME] > 0.0 else None)
        # every range but one taken at the fix time is carried (unchanged encoders included)
        carried = np.array(p.slots) < p.attempted - 1
        # The shift is itself measured: the fault area widens each range by a bound on the
        # odometry error of its shift (the set-membership view of docs/design.md §1, applied to motion), and
        # the least-squares weights add its variance; each with the heading it was turned with.
        shift = np.where(carried, shift_bound(self.robot, travelled, math.sqrt(max(heading_var_now, 0.0))), 0.0)
        bearings, bearing_margin, bearing_extra = None, None, None
        if p.bearings:
            # Each bearing was taken at its own heading: turn it into the frame of the last one
            # by the dead-reckoned turn since, so that one heading serves all (the snapshot
            # estimates it; the fault area needs none, only the bearings' differences).
            turned = np.array([float(dr_end[2]) - float(d[2]) for d in p.dr_at])
            bearings = np.array(p.bearings) - turned
            # An earlier bearing is off by the odometry's turn error, and by the angle its
            # marker's shift error subtends at the range (>= r - rho) it was taken at. (The
            # shift is turned into the world frame with the filter's heading, as the ranges'
            # are: its 3-sigma part of shift_bound is ~ d 3 sigma / r rad, ~1e-5 against xi.)
            reach = ranges - rho
            subtends = np.full(len(idx), 0.5 * math.pi)    # a shift beyond the range: no bound
            ok = reach > shift
            subtends[ok] = np.arcsin(shift[ok] / reach[ok])
            turn = turn_bound(self.robot, travelled, turned, reads_over, wheel_paths=paths_over,
                              bounded=self.sensor.noise is NoiseModel.UNIFORM)
            bearing_margin = np.where(carried, turn + subtends, 0.0)
            # The snapshot weighs each bearing with the same errors as variances: the turn's
            # (shared through the end reading and the nested reads' slip) and the shift's part
            # across the range, seen at the range.
            across_cos = [math.sqrt(max(1.0 - c * c, 0.0)) for c in along_cos]
            seen = shift_var(self.robot, travelled, max(heading_var0, 0.0), reads_over, across_cos,
                             slip_weight=weight_over, count_var=None if counts is None else np.diagonal(counts).T)
            seen = seen / np.maximum(ranges, 1e-9) ** 2
            bearing_extra = turn_cov(self.robot, travelled, turned, reads_over, weight_over,
                                     count_cov=counts) + np.diag(seen)
            bearing_extra[~carried, :] = 0.0
            bearing_extra[:, ~carried] = 0.0
        snap = snapshot_fix(shifted, ranges, rho, prior=x_est[:2], noise=self.sensor.noise,
                            bearings=bearings, bearing_error=self.sensor.bearing_error,
                            heading=float(x_est[2]) if bearings is not None else None,
                            bearing_margin=bearing_margin,
                            extra_var=shift_cov(self.robot, travelled, max(heading_var0, 0.0), reads_over,
                                                along_cos, across, slip_weight=weight_over, count_cov=counts),
                            fault_margin=shift, fault_markers=area_markers, bearing_extra_var=bearing_extra)
        fa = snap.fault_area
        truth = np.asarray(true_pose[:2], dtype=float)
        pad = self.k - len(idx)   # a marker lost mid-fix leaves its slot empty
        self._rows.append(dict(
            t=t, markers=p.measured + [-1] * pad, ranges=p.ranges + [math.nan] * pad,
            rho=rho.tolist() + [math.nan] * pad, true_position=truth,
            snapshot=snap.position, snapshot_cov=snap.covariance, fault_diameter=fa.diameter,
            contained=fa.contains(truth), nis=p.nis, n_accepted=p.accepted,
            predicted_tau=self._promise(p), fallback=p.fallback >= 0, beyond=p.beyond, unplanned=p.unplanned,
            note=p.note))
        self._polygons.append(fa.ring)

    def _promise(self, p: _Pending) -> float:
        """Return the plan's promise for this fix [m].

        The scheduled fix's; the schedule's promise of the fallback a fix measured instead; or,
        for a marker lost mid-fix, the same construction for the markers actually measured at
        the scheduled poses.
        """
        f = p.scheduled
        if f is None or not f.poses:
            return math.inf
        if tuple(p.measured) == tuple(f.markers):
            return float(f.predicted_tau)
        if p.fallback >= 0 and tuple(p.measured) == tuple(f.fallbacks[p.fallback]):
            return float(f.fallback_tau[p.fallback])
        poses = np.array(f.poses)
        area = promised_fault_area(self.sensor, self.robot, self.markers[p.measured], poses[p.slots],
                                   self.scenario.planning.heading_std, end=poses[-1],
                                   carried=np.array(p.slots) < len(poses) - 1)
        return math.inf if area.is_empty else float(area.diameter)

    def _static(self, markers: np.ndarray, truth: np.ndarray) -> np.ndarray:
        """Return the static PEF τ (the paper's) of each fix's subset at its true position, (F,) [m]."""
        out = np.full(len(markers), math.inf)
        full = np.all(markers >= 0, axis=1)
        if not full.any():
            return out
        subsets, which = np.unique(markers[full], axis=0, return_inverse=True)
        rows = np.flatnonzero(full)
        for j, sub in enumerate(subsets):
            sel = rows[which.ravel() == j]
            out[sel] = self.pef.tau_subset(truth[sel], sub)
        return out

    # -- result --------------------------------------------------------------------------

    def log(self) -> FixLog:
        for finished in self._finished:
            self._complete(*finished)
        self._finished.clear()
        rows, k = self._rows, self.k

        def col(name, shape, dtype=float):
            if not rows:
                return np.zeros((0, *shape), dtype=dtype)
            return np.array([r[name] for r in rows], dtype=dtype).reshape(len(rows), *shape)

        markers = col("markers", (k,), int)
        truth = col("true_position", (2,))
        return FixLog(
            t=col("t", ()), markers=col("markers", (k,), int), ranges=col("ranges", (k,)),
            rho=col("rho", (k,)), true_position=col("true_position", (2,)),
            snapshot=col("snapshot", (2,)), snapshot_cov=col("snapshot_cov", (2, 2)),
            fault_diameter=col("fault_diameter", ()), fault_polygons=list(self._polygons),
            contained=col("contained", (), bool), predicted_tau=col("predicted_tau", ()),
            static_tau=self._static(markers, truth),
            nis=col("nis", ()), n_accepted=col("n_accepted", (), int), fallback=col("fallback", (), bool),
            beyond_redundancy=col("beyond", (), bool), unplanned=col("unplanned", (), bool),
            notes=[r["note"] for r in rows])
