"""The lock of a sweep directory: one writing process at a time.

A process that writes a sweep directory ``DIR`` holds ``DIR/.lock``, a small JSON file with
its pid, host and start time (and, on Linux, the start tick of that pid so that a pid reused
by another process after a reboot or a wrap-around is not mistaken for the holder). The file
is created with ``O_CREAT | O_EXCL``, so of two processes racing for it exactly one wins;
the loser is refused with an :class:`~scenarios.errors.OutputError` naming the holder.

A lock left behind by a process that died without removing it (SIGKILL, a power cut) is
taken over, with a warning, when its holder is certainly gone: same host and the pid not
alive (or alive but started at another time). A lock of another host is never taken over:
from here we cannot tell whether that process still runs, so the message says how to remove
it by hand. The lock is removed when the holder leaves the ``with`` block, also on an
exception or Ctrl-C.

Within one process the lock is re-entrant (a count per directory), so that ``pefsim mc`` can
hold it over the sweep and the report it writes afterwards, while :func:`sim.montecarlo.engine.sweep`
takes it as well when called on its own.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path

from scenarios.errors import OutputError

LOCK_NAME = ".lock"
UNREADABLE_GRACE_S = 30.0
"""An unreadable lock younger than this may be one whose holder is writing it right now
(between ``O_EXCL`` and the write): it is respected. An older one is stale."""

_held: dict[Path, int] = {}
"""Locks this process holds, with their re-entry count."""


@dataclass(frozen=True)
class Holder:
    """Who holds a lock: pid, host, start time (ISO 8601, UTC) and the pid's start tick (Linux)."""

    pid: int
    host: str
    since: str
    pid_start: int | None = None

    def describe(self, root: Path) -> str:
        return f"{root} is being written by pid {self.pid} on host {self.host} since {self.since}"


def lock_path(root: Path) -> Path:
    return Path(root) / LOCK_NAME


def _pid_start(pid: int) -> int | None:
    """Start time of ``pid`` in clock ticks since boot (Linux /proc), None where unknown."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    # The command name (field 2) may hold spaces and parentheses: fields count from the last ")".
    fields = stat[stat.rfind(")") + 2:].split()
    try:
        return int(fields[19])  # field 22 of proc(5), the 20th after the name
    except (IndexError, ValueError):
        return None


def _alive(holder: Holder) -> bool:
    """Whether the holder (of this host) still runs."""
    try:
        os.kill(holder.pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by another user
        pass
    except OSError:
        return True
    if holder.pid_start is not None:
        now = _pid_start(holder.pid)
        if now is not None and now != holder.pid_start:
            return False  # the pid was reused by another process
    return True


def me() -> Holder:
    """Return the holder record of this process."""
    since = datetime.now(UTC).strftime("%Y-%m-%dT%H:%MZ")
    return Holder(os.getpid(), socket.gethostname(), since, _pid_start(os.getpid()))


def read_holder(root: Path) -> Holder | None:
    """Return the holder recorded in ``root``'s lock; None when there is no lock or it does not parse."""
    try:
        d = json.loads(lock_path(root).read_text(encoding="utf-8"))
        return Holder(int(d["pid"]), str(d["host"]), str(d["since"]),
                      None if d.get("pid_start") is None else int(d["pid_start"]))
    except (OSError, ValueError, KeyError, TypeError):
        return None


def check_free(root: Path) -> None:
    """Raise OutputError when another live process holds ``root``'s lock (reads only; writes nothing)."""
    root = Path(root)
    if root.resolve() in _held or not lock_path(root).exists():
        return
    holder = read_holder(root)
    if holder is not None and not _stale(holder):
        raise OutputError(_refusal(root, holder))


def _stale(holder: Holder) -> bool:
    return holder.host == socket.gethostname() and not _alive(holder)


def _refusal(root: Path, holder: Holder) -> str:
    if holder.host != socket.gethostname():
        return (f"{holder.describe(root)}; if that process is gone, delete {lock_path(root)} and "
                "resume")
    return holder.describe(root)


def _create(path: Path, holder: Holder) -> bool:
    """Create the lock file exclusively; False when it exists."""
    try:
        fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
    except FileExistsError:
        return False
    except OSError as exc:
        raise OutputError(f"{path}: cannot create the lock: {exc.strerror or exc}") from None
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(json.dumps(asdict(holder)) + "\n")
    return True


def _take_over(path: Path, seen: str) -> bool:
    """Remove a stale lock whose text was ``seen``; False if it changed meanwhile (someone else took it)."""
    aside = path.with_name(f"{path.name}.stale{os.getpid()}")
    try:
        os.rename(path, aside)
    except FileNotFoundError:
        return True  # another process removed it first; race for the new one
    try:
        if aside.read_text(encoding="utf-8", errors="replace") != seen:
            # We moved a lock someone created after we read the stale one: give it back.
            with contextlib.suppress(OSError):
                os.link(aside, path)
            return False
        return True
    finally:
        aside.unlink(missing_ok=True)


def acquire(root: Path, warn: Callable[[str], None]) -> None:
    """Take ``root``'s lock (``root`` must exist); raises OutputError naming the holder if it is held."""
    root, key = Path(root), Path(root).resolve()  # messages name the directory as given
    if key in _held:
        _held[key] += 1
        return
    path = lock_path(root)
    mine = me()
    for _ in range(3):  # a take-over lost to another process retries once or twice, then refuses
        if _create(path, mine):
            _held[key] = 1
            return
        try:
            seen = path.read_text(encoding="utf-8", errors="replace")
            age = time.time() - path.stat().st_mtime
        except FileNotFoundError:
            continue  # released between our attempt and the read
        holder = read_holder(root)
        if holder is None and age < UNREADABLE_GRACE_S:
            raise OutputError(f"{root} is being locked by another process ({path} is being written)")
        if holder is not None and not _stale(holder):
            raise OutputError(_refusal(root, holder))
        who = ("an unreadable lock" if holder is None else
               f"the lock of pid {holder.pid} (since {holder.since}), which is not running")
        if _take_over(path, seen):
            warn(f"pefsim: warning: {root}: took over {who}")
    holder = read_holder(root)
    raise OutputError(_refusal(root, holder) if holder else f"{root}: cannot take the lock {path}")


def release(root: Path) -> None:
    """Give up ``root``'s lock (the file goes when the outermost holder in this process leaves)."""
    root, key = Path(root), Path(root).resolve()
    count = _held.get(key, 0)
    if count > 1:
        _held[key] = count - 1
        return
    _held.pop(key, None)
    holder = read_holder(root)
    if holder is not None and holder.pid == os.getpid() and holder.host == socket.gethostname():
        lock_path(root).unlink(missing_ok=True)


@contextlib.contextmanager
def held(root: str | Path, warn: Callable[[str], None]):
    """Hold ``root``'s lock for the ``with`` block (see :func:`acquire`)."""
    root = Path(root)
    acquire(root, warn)
    try:
        yield
    finally:
        release(root)
