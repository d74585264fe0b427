"""The file formats a figure is written in, chosen by the output file's extension.

A figure is written at exactly the path given: the extension names the format, and a path
without a known one is refused before any work (matplotlib would otherwise append ``.png`` to a
path without an extension, and fail only after the map or plan was computed on an unknown one).
"""

from __future__ import annotations

import os
from pathlib import Path

from scenarios.errors import OutputError

FIGURE_FORMATS = {".png": "png", ".pdf": "pdf", ".svg": "svg"}
"""Extension (lower case) -> matplotlib format name."""


def figure_format(path: str | os.PathLike[str]) -> str:
    """Return the matplotlib format of a figure to be written at ``path``.

    Parameters
    ----------
    path : str or path-like
        The output file; its extension (any case) names the format.

    Returns
    -------
    str
        ``"png"``, ``"pdf"`` or ``"svg"``.

    Raises
    ------
    OutputError
        One line naming the path and the extensions accepted.
    """
    suffix = Path(path).suffix
    fmt = FIGURE_FORMATS.get(suffix.lower())
    if fmt is None:
        what = f"extension {suffix!r}" if suffix else "no extension"
        raise OutputError(f"{path}: cannot write a figure with {what}: expected "
                          f"{', '.join(FIGURE_FORMATS)}")
    return fmt
