"""What ``pefsim run`` prints of a run: a lone robot's episode, or each robot of a fleet's."""

from __future__ import annotations

from typing import Any

MM = 1000.0
"""Millimetres per metre (errors print in mm)."""


def status_line(s: dict) -> str:
    """Say what a run did (its ``status``, and where it touched, stalled or waited) in one line."""
    parts = [f"status {s.get('status', 'ok')}"]
    if s.get("collisions"):
        at = f"({s['contact_x']:.2f}, {s['contact_y']:.2f})" if s.get("contact_x") is not None else "(?)"
        along = f" s={s['contact_s']:.1f} m" if s.get("contact_s") is not None else ""
        parts.append(f"{s['collisions']} contact(s), first with {s.get('contact_with') or 'something'} at {at}"
                     f"{along} t={s['contact_t']:.1f} s")
    if s.get("stuck"):
        parts.append(f"no progress for {s['stall_time']:.1f} s (bound {s['stuck_bound']:.1f} s) from "
                     f"({s['stall_x']:.2f}, {s['stall_y']:.2f}) t={s['stall_t']:.1f} s")
    if s.get("deadlocked"):
        other = f" for {s['waited_for']}" if s.get("waited_for") else ""
        parts.append(f"waited {s['longest_wait']:.1f} s (bound {s['wait_bound']:.1f} s) at "
                     f"({s['wait_x']:.2f}, {s['wait_y']:.2f}){other}")
    return "; ".join(parts)


def episode_lines(scenario: Any, task_index: int, s: dict) -> list[str]:
    """Return the lines that report a lone robot's episode of task ``task_index`` with summary ``s``."""
    task = scenario.tasks[task_index]
    return [f"{scenario.name}: task {task_index} {task.start} -> {task.goal}, seed {s['seed']}",
            f"  {status_line(s)}",
            f"  {'reached' if s['reached'] else 'NOT reached'} after {s['duration']:.1f} s "
            f"({s['steps']} steps, {s['fixes']} fixes)",
            f"  position error: rmse {s['rmse'] * MM:.2f} mm, max {s['max_error'] * MM:.2f} mm; "
            f"predicted bound max {s['max_predicted_tau'] * MM:.2f} mm; eps_max {s['eps_max'] * MM:.1f} mm",
            f"  samples over eps_max: {s['violations']}; mean NEES {s['mean_nees']:.2f} (3 dof), "
            f"mean NIS {s['mean_nis']:.2f} (1 dof)"]


def fleet_lines(scenario: Any, summaries: list[tuple[str, dict]], collisions: int, duration: float) -> list[str]:
    """Return the lines that report a fleet's run: its robots' ``(name, summary)``, overlaps and duration [s]."""
    out = [f"{scenario.name}: fleet of {len(summaries)}, seed {summaries[0][1]['seed']}, "
           f"{duration:.1f} s, footprints overlapped {collisions} times"]
    for name, s in summaries:
        out.append(f"  {name}: {status_line(s)}")
        arrived = f"reached its dock at {s['arrival']:.1f} s" if s["reached"] else "NOT reached"
        out.append(f"  {name}: {arrived}, "
                   f"waited {s['wait_time']:.1f} s; {s['fixes']} fixes, {s['robot_blocked']} scheduled lines of "
                   f"sight hidden by robots, {s['fallback_fixes']} fallback, {s['failed_fixes']} failed; "
                   f"max error {s['max_error'] * MM:.2f} mm (eps_max {s['eps_max'] * MM:.1f} mm), "
                   f"{s['violations']} samples over")
    return out
