"""Which of a set of files changed since the last look: polling, portable, no dependency.

A file's state is its modification time and size, and (read only when those moved) a hash of
its content: a save that writes the same bytes is not a change, and an editor that replaces the
file (write to a temporary, rename) is seen like one that writes in place.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable
from pathlib import Path

Stamp = tuple[int, int, bytes] | None
"""(mtime [ns], size [bytes], content hash) of a file; None when it cannot be read."""


def _stamp(path: Path, before: Stamp) -> Stamp:
    try:
        st = os.stat(path)
        if before is not None and (st.st_mtime_ns, st.st_size) == before[:2]:
            return before
        with open(path, "rb") as f:
            digest = hashlib.file_digest(f, "blake2b").digest()
    except OSError:
        return None
    return st.st_mtime_ns, st.st_size, digest


class FileSet:
    """The files of a scenario and their last seen state.

    Parameters
    ----------
    paths : iterable of path-like
        Files to follow (missing ones too: they count as changed once they appear).
    """

    def __init__(self, paths: Iterable[str | os.PathLike[str]]):
        self.stamps: dict[Path, Stamp] = {}
        self.follow(paths)

    def follow(self, paths: Iterable[str | os.PathLike[str]]) -> None:
        """Follow exactly ``paths`` from now on, keeping the state of those already followed."""
        new = [Path(p) for p in paths]
        self.stamps = {p: self.stamps[p] if p in self.stamps else _stamp(p, None) for p in new}

    def digest(self, path: Path) -> bytes | None:
        """Return the content hash of ``path`` as last seen (None: missing or unreadable)."""
        stamp = self.stamps.get(Path(path))
        return None if stamp is None else stamp[2]

    def changed(self) -> list[Path]:
        """Return the files whose content differs from the last call's (or from :meth:`follow`'s), in order."""
        out = []
        for path, before in self.stamps.items():
            now = _stamp(path, before)
            if (now is None) != (before is None) or (now is not None and now[2] != before[2]):
                out.append(path)
            self.stamps[path] = now
        return out
