"""Silence pybullet's C-level output and import it quietly.

pybullet prints a build banner on stderr when imported and ``b3Warning``/``b3Printf`` lines
on stdout from C code when connecting and loading URDFs. Python's ``sys.stdout`` redirection
cannot catch C ``printf``, so :func:`silenced` points file descriptors 1 and 2 at
``/dev/null`` for the duration of the block (``os.dup2``) and restores them afterwards.

Every module of :mod:`sim.physics` takes pybullet from here (``from sim.physics.quiet import pb``)
so the banner never reaches the user.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator


@contextlib.contextmanager
def silenced() -> Iterator[None]:
    """Discard everything written to file descriptors 1 and 2 inside the block.

    Python-level buffers are flushed first so earlier output is not lost or reordered.
    If the descriptors cannot be duplicated (an unusual host), the block runs unsilenced.
    """
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    try:
        saved = (os.dup(1), os.dup(2))
    except OSError:
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        yield
    finally:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)


with silenced():
    import pybullet as pb  # noqa: E402  (imported here so its banner is silenced)

__all__ = ["pb", "silenced"]
