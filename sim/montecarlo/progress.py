"""A progress bar for long sweeps: runs done, rate and ETA on stderr, silent off a terminal."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from typing import Protocol


class Progress(Protocol):
    def update(self, n: int = 1) -> None: ...

    def write(self, message: str) -> None: ...


class _Quiet:
    """Stands in for the bar when it is off: counts nothing, prints messages plainly."""

    def update(self, n: int = 1) -> None:
        pass

    def write(self, message: str) -> None:
        print(message, file=sys.stderr)


class _Bar:
    def __init__(self, bar) -> None:
        self.bar = bar

    def update(self, n: int = 1) -> None:
        self.bar.update(n)

    def write(self, message: str) -> None:
        self.bar.write(message, file=sys.stderr)  # above the bar, which would otherwise smear it


@contextlib.contextmanager
def progress_bar(total: int, initial: int = 0, enabled: bool | None = None,
                 desc: str = "runs") -> Iterator[Progress]:
    """Show a tqdm bar on stderr counting runs from ``initial`` to ``total``.

    Parameters
    ----------
    total : int
        Runs the sweep will have when complete.
    initial : int
        Runs already done (a resumed sweep starts there).
    enabled : bool, optional
        Force the bar on or off; default on only when stderr is a terminal, so that logs and
        CI output stay free of carriage-return noise.
    desc : str
        Label in front of the bar.
    """
    if enabled is None:
        enabled = sys.stderr.isatty()
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
