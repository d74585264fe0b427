"""Shared test scenarios: the tiny worlds several test modules build."""

from __future__ import annotations


def flat_text(size: float = 30.0, extra: str = "") -> str:
    """TOML of an empty square floor of ``size`` metres with two markers on its south wall.

    ``extra`` is appended (more tables or keys, e.g. a ``[robot]`` section).
    """
    return (f'name = "flat"\n[workspace]\nsize = [{size}, {size}]\n'
            f'[[markers]]\nid = "a"\nposition = [0.0, 0.0]\n[[markers]]\nid = "b"\nposition = [{size}, 0.0]\n'
            f'[sensor]\n[planning]\neps_max = 0.05\n{extra}')
