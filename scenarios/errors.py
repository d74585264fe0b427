"""The one exception tree of pefsim.

Every error a user can cause derives from :class:`PefsimError`; the CLI prints its message
on one line and exits with code 2. Anything else is a bug and shows a traceback.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

#: Longest message an error prints [characters]: a value or a file name beyond it is elided in
#: the middle, so that an error stays one readable line whatever the input held.
MAX_MESSAGE = 1000


def elide(text: str, limit: int) -> str:
    """Return ``text`` cut to at most ``limit`` characters by eliding its middle (" ... ")."""
    if len(text) <= limit:
        return text
    keep = max(0, limit - 5)
    return f"{text[:keep - keep // 3]} ... {text[len(text) - keep // 3:]}" if keep else text[:limit]


class PefsimError(Exception):
    """Root of all errors caused by input (files, arguments, infeasible requests).

    The message is one line of at most :data:`MAX_MESSAGE` characters (longer ones are elided
    in the middle, line breaks become spaces).
    """

    def __init__(self, message: str = "", *args: object) -> None:
        super().__init__(elide(" ".join(str(message).split("\n")), MAX_MESSAGE), *args)


class ScenarioError(PefsimError):
    """A scenario file is malformed or inconsistent.

    The message names the file, the key path and the offending value, e.g.
    ``warehouse.toml: markers[3].position: expected [x, y] inside the workspace, got [31.0, 2.0]``.
    """


class PlanningError(PefsimError):
    """The planner cannot satisfy a request (no admissible route, unreachable dock, ...)."""


class SimulationError(PefsimError):
    """An episode cannot run as asked (unknown task, no visible markers at the start, ...)."""


class OutputError(PefsimError):
    """A result cannot be written (unwritable path, conflicting output directory, ...)."""


class ScenarioWarning(UserWarning):
    """Input pefsim accepts although it is irregular (a route graph's repeated edge ids, ...).

    The message is one line naming the file, key and values; the CLI prints it as
    ``pefsim: warning: ...`` on stderr.
    """


@contextlib.contextmanager
def output_errors(path, action: str) -> Iterator[None]:
    """Turn an ``OSError`` raised inside the block into one :class:`OutputError` line.

    Parameters
    ----------
    path : str or path-like
        The file or directory being written (named in the message).
    action : str
        What could not be done, for the message ("write the figure", "create the output
        directory", ...).

    Raises
    ------
    OutputError
        ``"<path>: cannot <action>: <reason>"``.
    """
    try:
        yield
    except OSError as exc:
        raise OutputError(f"{path}: cannot {action}: {exc.strerror or exc}") from None
