"""The library speaks in parameters: no error or warning it raises names a command-line flag.

Read statically with :mod:`ast`: every string in a call of an ``...Error``/``...Warning`` class
(or ``warnings.warn``) in the packages below the program. ``pefsim.sweep(sc, runs=0)`` answers
``runs: ...``; only ``cli`` speaks of ``--runs``.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LIBRARY = ("jit", "scenarios", "estimators", "planner", "sim", "validation", "interop", "pefsim")
FLAG = re.compile(r"(^|[\s(])--[a-z][a-z-]*")
"""A long option as a user types it (``--runs``, ``(--out``), not an arrow or a rule of dashes."""


def _flag_messages(text: str, where: str) -> list[str]:
    """``where:line: text`` of each string naming a flag in an error or warning raised in ``text``."""
    found = []
    for node in ast.walk(ast.parse(text)):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
        if name.endswith(("Error", "Warning")) or name == "warn":
            found += [f"{where}:{node.lineno}: {c.value}" for c in ast.walk(node)
                      if isinstance(c, ast.Constant) and isinstance(c.value, str) and FLAG.search(c.value)]
    return found


def test_no_library_message_names_a_flag():
    found = [line for package in LIBRARY for path in sorted((ROOT / package).rglob("*.py"))
             for line in _flag_messages(path.read_text(encoding="utf-8"), str(path.relative_to(ROOT)))]
    assert not found, "\n".join(found)


def test_a_negative_control_of_the_scan():
    code = 'def f(n):\n    raise ScenarioError(f"--runs: expected a positive number, got {n}")\n'
    assert _flag_messages(code, "x.py") == ["x.py:2: --runs: expected a positive number, got "]
    assert _flag_messages('raise ScenarioError(f"runs: expected -> {n}")\n', "x.py") == []
