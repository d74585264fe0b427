"""Pure pursuit on an ideal unicycle: reaches the goal, tracks closely, respects its limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.episode.follower import PurePursuit, wheel_speeds


def _densify(corners, step=0.02):
    pts = [corners[0]]
    for a, b in zip(corners[:-1], corners[1:], strict=True):
        n = max(1, int(np.ceil(np.hypot(*(np.subtract(b, a))) / step)))
        pts += [np.add(a, (np.subtract(b, a)) * t) for t in np.linspace(0, 1, n + 1)[1:]]
    return np.array(pts)


def _drive(path, pose, dt=1 / 60, t_max=120.0):
    f = PurePursuit(path=path, speed=np.full(len(path), 1.0), max_speed=1.0, max_yaw_rate=1.5)
    pose = np.array(pose, dtype=float)
    trace, cmds = [pose.copy()], []
    for _ in range(int(t_max / dt)):
        c = f.command(pose, dt)
        cmds.append((c.v, c.omega))
        if c.done:
            break
        pose[2] += c.omega * dt
        pose[0] += c.v * math.cos(pose[2]) * dt
        pose[1] += c.v * math.sin(pose[2]) * dt
        trace.append(pose.copy())
    return c, np.array(trace), np.array(cmds)


def _cross_track(path, trace):
    d = np.sqrt(((trace[:, None, :] - path[None, :, :]) ** 2).sum(-1))
    return d.min(axis=1)


def test_reaches_goal_on_an_l_shaped_path():
    path = _densify([(0, 0), (6, 0), (6, 4)])
    c, trace, cmds = _drive(path, (0, 0, 0))
    assert c.done
    assert np.hypot(*(trace[-1, :2] - path[-1])) < 0.05
    # pure pursuit cuts corners by about the lookahead; on straights it converges
    assert _cross_track(path, trace[:, :2]).max() < 0.3
    assert np.abs(cmds[:, 0]).max() <= 1.0 + 1e-9
    assert np.abs(cmds[:, 1]).max() <= 1.5 + 1e-9
    assert np.abs(np.diff(cmds[:-1, 0])).max() <= 0.5 / 60 + 1e-9  # acceleration limit
    assert cmds[-2, 0] <= 0.03  # the final stop is from creeping speed


def test_turns_in_place_when_facing_away():
    path = _densify([(0, 0), (3, 0)])
    f = PurePursuit(path=path, speed=np.full(len(path), 1.0), max_speed=1.0, max_yaw_rate=1.5)
    c = f.command(np.array([0.0, 0.0, math.pi]), 1 / 60)
    assert c.v == 0.0 and abs(c.omega) > 0
    _, trace, _ = _drive(path, (0, 0, math.pi))
    assert np.hypot(*(trace[-1, :2] - path[-1])) < 0.05


def test_a_wrong_start_fails_to_track():
    # negative control: started 2 m off the path, the early cross-track error is large
    path = _densify([(0, 0), (6, 0)])
    _, trace, _ = _drive(path, (0, 2.0, 0))
    assert _cross_track(path, trace[:30, :2]).max() > 1.0


def test_wheel_speeds_invert_the_unicycle():
    wl, wr = wheel_speeds(0.8, 0.4, 0.1, 0.5)
    r, b = 0.1, 0.5
    assert (wl + wr) * r / 2 == pytest.approx(0.8)
    assert (wr - wl) * r / b == pytest.approx(0.4)
