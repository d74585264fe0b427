"""Output paths checked before any work: names the file system takes, and no two outputs at one path.

A name longer than the file system allows fails only when the file is opened, which for most
outputs is after the work (a plan, a sweep); two outputs given the same path would overwrite one
with the other. Both are refused here, in one line naming the parameter and the path, before any
work starts.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from scenarios.errors import OutputError, elide
from scenarios.limits import MAX_NAME_BYTES, MAX_PATH_BYTES


def check_output_names(outputs: Mapping[str, str | os.PathLike[str] | None]) -> None:
    """Refuse output paths that are too long, or that name one file twice.

    Parameters
    ----------
    outputs : mapping of str to path or None
        Parameter name (e.g. ``"routes"``) -> the path given (None: not
        asked for).

    Raises
    ------
    OutputError
        A path component over :data:`~scenarios.limits.MAX_NAME_BYTES` bytes or a path over
        :data:`~scenarios.limits.MAX_PATH_BYTES`; two options naming the same file.
    """
    seen: dict[str, str] = {}
    for option, path in outputs.items():
        if path is None:
            continue
        text = os.fsdecode(path)
        shown = elide(text, 200)
        size = len(os.fsencode(text))
        if size > MAX_PATH_BYTES:
            raise OutputError(f"{shown}: {option}: path too long ({size} bytes, at most {MAX_PATH_BYTES})")
        for part in Path(text).parts:
            n = len(os.fsencode(part))
            if n > MAX_NAME_BYTES:
                raise OutputError(f"{shown}: {option}: file name too long ({n} bytes, at most {MAX_NAME_BYTES} "
                                  f"a name)")
        key = _identity(text)
        if key in seen:
            raise OutputError(f"{shown}: {seen[key]} and {option} name the same file: one would overwrite "
                              f"the other")
        seen[key] = option


def _identity(text: str) -> str:
    """Return a key equal for two spellings of one path (relative, ``..``, a symbolic link on the way)."""
    path = Path(text).expanduser()
    try:
        parent = path.absolute().parent.resolve()
    except (OSError, RuntimeError):  # a link loop on the way: the write names it; compare as spelled
        parent = Path(os.path.abspath(path)).parent
    return os.path.normcase(str(parent / path.name))
