"""Typed reading of one TOML table, with the key path of every value for error messages.

A :class:`Table` wraps a dict parsed from TOML. Each getter checks the type and range of one
key and raises :class:`~scenarios.errors.ScenarioError` naming file, key path and value;
:meth:`Table.done` rejects keys nobody asked for, since in a scenario they are typos.
"""

from __future__ import annotations

import math
from typing import Any

from scenarios.errors import ScenarioError, elide

_MISSING = object()

#: Largest magnitude of any number in a scenario unless its key says less: beyond it a value is
#: a typo or a fuzzer's, and downstream arithmetic (squares, grids, polygons) would overflow.
MAX_NUMBER = 1e9
#: Largest magnitude of a coordinate or size [m]: 1e8 m, room for UTM northings (up to 1e7 m)
#: in a workspace.origin, far below where squares of coordinates lose all precision.
MAX_COORD = 1e8


#: Longest rendering of a value in a message [characters]: a long list or string is cut, so that
#: an error names a 20 000-vertex polygon or a 5000-character name in one short line.
MAX_SHOWN = 200


def show(value: Any, limit: int = MAX_SHOWN) -> str:
    """Render a value the way the user wrote it in TOML (roughly), in at most about ``limit`` characters.

    Containers are walked only until the rendering is that long (a value built from YAML
    aliases may be exponentially large: it is never expanded in full).
    """
    out: list[str] = []
    budget = [limit]

    def put(text: str) -> bool:
        out.append(text[:max(budget[0], 0)])
        budget[0] -= len(text)
        return budget[0] > 0

    def walk(v: Any) -> bool:
        if isinstance(v, str):
            return put(f'"{v}"')
        if isinstance(v, bool):
            return put("true" if v else "false")
        if isinstance(v, (list, tuple, dict)):
            items = v.items() if isinstance(v, dict) else v
            opening, closing = ("{", "}") if isinstance(v, dict) else ("[", "]")
            if not put(opening):
                return False
            for i, item in enumerate(items):
                if i and not put(", "):
                    return False
                if isinstance(v, dict):
                    if not put(f"{item[0]} = "):
                        return False
                    item = item[1]
                if not walk(item):
                    return False
            return put(closing)
        return put(repr(v))

    if walk(value):
        return "".join(out)
    return "".join(out) + " ..."


def show_path(path: Any) -> str:
    """Return a file name for a message, with the middle of a very long one elided."""
    return elide(str(path), MAX_SHOWN)


class Table:
    """One TOML table being read; ``path`` is its key path ('' for the root)."""

    def __init__(self, data: Any, file: str, path: str = "") -> None:
        self.file = file
        self.path = path
        if not isinstance(data, dict):
            self.fail(path or "<root>", "expected a table", data)
        self.data: dict[str, Any] = data
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def fail(self, key: str, expected: str, value: Any = _MISSING) -> None:
        got = "" if value is _MISSING else f", got {show(value)}"
        raise ScenarioError(f"{self.file}: {key}: {expected}{got}")

    def has(self, name: str) -> bool:
        return name in self.data

    def raw(self, name: str, default: Any = _MISSING) -> Any:
        self.used.add(name)
        if name not in self.data:
            if default is _MISSING:
                self.fail(self.key(name), "missing required key")
            return default
        return self.data[name]

    def number(self, name: str, default: Any = _MISSING, *, low: float | None = None,
               high: float | None = None, low_open: bool = False, what: str = "a number") -> float:
        """Read a finite float in [low, high] (``low_open``: strictly above ``low``)."""
        v = self.raw(name, default)
        return self.check_number(self.key(name), v, low=low, high=high, low_open=low_open, what=what)

    def check_number(self, key: str, v: Any, *, low: float | None = None, high: float | None = None,
                     low_open: bool = False, what: str = "a number") -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(key, f"expected {what}", v)
        v = float(v)
        if not math.isfinite(v):
            self.fail(key, f"expected a finite {what.removeprefix('a ')}", v)
        if low is not None and (v <= low if low_open else v < low):
            self.fail(key, f"expected {what} {'>' if low_open else '>='} {low:g}", v)
        if high is not None and v > high:
            self.fail(key, f"expected {what} <= {high:g}", v)
        if abs(v) > MAX_NUMBER:
            self.fail(key, f"expected {what} of magnitude at most {MAX_NUMBER:g}", v)
        return v

    def integer(self, name: str, default: Any = _MISSING, *, low: int | None = None,
                high: int | None = None) -> int:
        v = self.raw(name, default)
        if isinstance(v, bool) or not isinstance(v, int):
            self.fail(self.key(name), "expected an integer", v)
        bound = MAX_NUMBER if high is None else max(high, MAX_NUMBER)  # a key may allow more (a seed)
        if abs(v) > bound:
            self.fail(self.key(name), f"expected an integer of magnitude at most {bound:.3g}", v)
        if low is not None and v < low:
            self.fail(self.key(name), f"expected an integer >= {low}", v)
        if high is not None and v > high:
            self.fail(self.key(name), f"expected an integer <= {high}", v)
        return int(v)

    def string(self, name: str, default: Any = _MISSING, *, choices: tuple[str, ...] | None = None) -> str:
        v = self.raw(name, default)
        if not isinstance(v, str):
            self.fail(self.key(name), "expected a string", v)
        if choices is not None and v not in choices:
            self.fail(self.key(name), "expected one of " + ", ".join(f'"{c}"' for c in choices), v)
        return v

    def vector(self, name: str, n: int, default: Any = _MISSING, *, what: str | None = None,
               positive: bool = False) -> tuple[float, ...]:
        """Read a list of exactly ``n`` finite numbers."""
        v = self.raw(name, default)
        return self.check_vector(self.key(name), v, n, what=what, positive=positive)

    def check_vector(self, key: str, v: Any, n: int, *, what: str | None = None,
                     positive: bool = False) -> tuple[float, ...]:
        what = what or f"a list of {n} numbers"
        ok = isinstance(v, (list, tuple)) and len(v) == n and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)
        if not ok:
            self.fail(key, f"expected {what}", v)
        if positive and any(x <= 0 for x in v):
            self.fail(key, f"expected {what} with positive entries", v)
        if any(abs(x) > MAX_COORD for x in v):
            self.fail(key, f"expected {what} of magnitude at most {MAX_COORD:g}", v)
        return tuple(float(x) for x in v)

    def table(self, name: str, default: Any = _MISSING) -> Table:
        v = self.raw(name, default)
        return Table(v, self.file, self.key(name))

    def array_of_tables(self, name: str) -> list[Table]:
        v = self.raw(name, [])
        if not isinstance(v, list):
            self.fail(self.key(name), "expected an array of tables ([[...]])", v)
        return [Table(item, self.file, f"{self.key(name)}[{i}]") for i, item in enumerate(v)]

    def done(self) -> None:
        """Reject keys that were never read: in a scenario they are typos."""
        for k in self.data:
            if k not in self.used:
                self.fail(self.key(k), "unknown key", self.data[k])
