"""Why a path given as an input file cannot be read as one, said in a few words.

A FIFO or a device given as a scenario, floor plan or route graph would block the read or never
end it, a directory is not a file, and a symbolic link that points at itself is not a missing
file: each reader names the cause it found (``pathlib``'s ``is_file`` and ``exists`` answer
False for all of them alike).
"""

from __future__ import annotations

import errno
import stat
from pathlib import Path

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def unreadable_because(path: Path) -> str | None:
    """Return why ``path`` is not a regular file one can read (``"no such file"``, ...), or None if it is one.

    Parameters
    ----------
    path : Path
        The input file, as it will be opened.

    Returns
    -------
    str or None
        ``"no such file"``, ``"a directory, not a regular file"``, ``"a FIFO (named pipe), not a
        regular file"``, ``"a symbolic link loop"``, the file system's reason (``"File name too
        long"``), or None for a regular file.
    """
    try:
        mode = path.stat().st_mode  # follows links, as the read will
    except OSError as exc:
        if exc.errno == errno.ENOENT:
            return "no such file" if not path.is_symlink() else "no such file (a symbolic link to nothing)"
        if exc.errno == errno.ELOOP:
            return "a symbolic link loop (it leads back to itself)"
        return exc.strerror or str(exc)
    if stat.S_ISREG(mode):
        return None
    kind = next((what for test, what in _KINDS if test(mode)), "a special file")
    return f"{kind}, not a regular file"
