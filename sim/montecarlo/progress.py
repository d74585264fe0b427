"""Progress of long sweeps on stderr: a tqdm bar on a terminal, a line at least every 30 s off one.

Off a terminal (a log, CI, a pipe) a bar's carriage returns are noise, and silence for the
minutes a sweep of a large map takes looks like a hang: :class:`Lines` prints
``pefsim: D of N runs done (E s, R runs/min)`` every :data:`PERIOD` seconds, from a timer thread,
so that a line comes even while a single long run holds every worker. A sweep shorter than
:data:`PERIOD` prints nothing. Standard output is never written (``--json`` stays alone there).
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Protocol

PERIOD = 30.0
"""Seconds between two progress lines off a terminal."""


class Progress(Protocol):
    def update(self, n: int = 1) -> None: ...

    def write(self, message: str) -> None: ...


class _Quiet:
    """Stands in for the bar when it is off: counts nothing, prints messages plainly."""

    def update(self, n: int = 1) -> None:
        pass

    def write(self, message: str) -> None:
        print(message, file=sys.stderr)


class Lines:
    """Runs done of runs asked, as a line every ``period`` seconds (off a terminal).

    Parameters
    ----------
    total, initial : int
        Runs the sweep will have, and those already done.
    desc : str
        What is counted (plural).
    verb : str
        What happened to them.
    period : float, optional
        Seconds between lines [s]; default :data:`PERIOD`.
    clock : callable
        Monotonic clock [s] (tests pass a fake one).
    emit : callable
        Receives each line (default: print to stderr).
    """

    def __init__(self, total: int, initial: int = 0, desc: str = "runs", period: float | None = None,
                 clock: Callable[[], float] = time.monotonic, emit: Callable[[str], None] | None = None,
                 verb: str = "done") -> None:
        self.total, self.done, self.desc, self.verb, self.clock = total, initial, desc, verb, clock
        self.period = PERIOD if period is None else period
        self._initial = initial
        self.emit = emit or (lambda line: print(line, file=sys.stderr, flush=True))
        self.start = self.last = clock()
        self._lock = threading.Lock()

    def update(self, n: int = 1) -> None:
        with self._lock:
            self.done += n
        self.tick()

    def write(self, message: str) -> None:
        self.emit(message)

    def due(self) -> float:
        """Return the seconds until the next line is due (0 or less: now)."""
        return self.period - (self.clock() - self.last)

    def tick(self) -> None:
        """Print the line if one is due."""
        with self._lock:
            now = self.clock()
            if now - self.last < self.period:
                return
            self.last = now
            elapsed = now - self.start
            rate = 60.0 * (self.done - self._initial) / elapsed if elapsed > 0 else 0.0
            line = (f"pefsim: {self.done} of {self.total} {self.desc} {self.verb} ({elapsed:.0f} s, "
                    f"{rate:.1f} {self.desc}/min)")
        self.emit(line)


class _Bar:
    def __init__(self, bar) -> None:
        self.bar = bar

    def update(self, n: int = 1) -> None:
        self.bar.update(n)

    def write(self, message: str) -> None:
        self.bar.write(message, file=sys.stderr)  # above the bar, which would otherwise smear it


@contextlib.contextmanager
def progress_bar(total: int, initial: int = 0, enabled: bool | None = None,
                 desc: str = "runs", verb: str = "done") -> Iterator[Progress]:
    """Show a tqdm bar on stderr counting runs from ``initial`` to ``total``.

    Parameters
    ----------
    total : int
        Runs the sweep will have when complete.
    initial : int
        Runs already done (a resumed sweep starts there).
    enabled : bool, optional
        Force the bar on or off; default on when stderr is a terminal, and off one a line every
        :data:`PERIOD` seconds (:class:`Lines`), so that logs and CI output stay free of
        carriage-return noise and still show a long sweep moving.
    desc : str
        Label in front of the bar: what is counted.
    verb : str
        What happened to them (the lines off a terminal).
    """
    if enabled is None:
        if not sys.stderr.isatty():
            with progress_lines(total, initial, desc, verb) as lines:
                yield lines
            return
        enabled = True
    if not enabled:
        yield _Quiet()
        return
    from tqdm import tqdm

    bar = tqdm(total=total, initial=initial, desc=desc, unit="run", file=sys.stderr, dynamic_ncols=True,
               smoothing=0.1)
    try:
        yield _Bar(bar)
    finally:
        bar.close()


@contextlib.contextmanager
def progress_lines(total: int, initial: int = 0, desc: str = "runs", verb: str = "done") -> Iterator[Lines]:
    """Yield a :class:`Lines` whose timer thread prints its line whenever one is due, until the block ends."""
    lines = Lines(total, initial, desc, verb=verb)
    stop = threading.Event()

    def beat() -> None:
        while not stop.wait(max(lines.due(), 0.01)):
            lines.tick()

    timer = threading.Thread(target=beat, name="pefsim-progress", daemon=True)
    timer.start()
    try:
        yield lines
    finally:
        stop.set()
        timer.join()
