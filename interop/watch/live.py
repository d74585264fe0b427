"""``pefsim watch`` end to end: a scenario's files followed (:mod:`interop.watch.loop`) into a live rerun view.

The view is logged to a stream of :mod:`interop.recording.live`: the map and the route network
first, the plans when they follow (seconds on a large floor).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path

from interop.recording import close
from interop.recording.live import log_plans, log_view, open_live
from interop.watch.loop import POLL_INTERVAL, watch_files
from scenarios.errors import PefsimError
from scenarios.load import resolve


def watch_live(scenario: str | Path, *, save: str | os.PathLike[str] | None = None, connect: str | None = None,
               on_update: Callable[..., None] | None = None, on_error: Callable[[PefsimError], None] | None = None,
               interval: float | None = None, max_updates: int | None = None,
               stop: threading.Event | None = None) -> int:
    """Show ``scenario`` live in rerun and update the view whenever its files are saved.

    Parameters and return value: :func:`pefsim.watch`'s.
    """
    path = resolve(scenario)
    rec = open_live(path.name, save=save, connect=connect)

    contours: dict = {}  # the region's contour by tiles: an edit re-traces the tiles it changed

    def show(step, view) -> None:  # the map first: the plans follow (seconds on the hall)
        log_view(rec, step, view.scenario, view.pef_map, view.reports, None, {}, view.summary(), contours=contours)

    def show_plans(step, view) -> None:
        log_plans(rec, step, view.scenario, view.plans, view.unplanned, view.summary())

    try:
        return watch_files(path, show, show_plans=show_plans, on_update=on_update, on_error=on_error,
                           interval=POLL_INTERVAL if interval is None else interval,
                           max_updates=max_updates, stop=stop)
    finally:
        close(rec)
