"""Edge labels that do not overlap: each beside its own segment, clear of the others' labels.

A label is horizontal text of height h whose box is taken as ``CHAR_WIDTH * h`` per character
wide and h high (a DXF viewer's standard fonts stay within it). For each segment, in order,
candidate boxes are centred beside the segment, off it along its normal by half the box's
extent in that direction plus a gap (so the box does not cover its own line), at fractions
:data:`ALONG` of its length, on either side, then twice and three times as far off; the first
candidate that overlaps no label placed before is taken. A segment's midpoint comes first, so
labels of the edges meeting at a node spread along their edges instead of piling up at it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

CHAR_WIDTH = 0.9
"""Width of a character per unit of text height, an upper bound for the usual CAD fonts [-]."""
ALONG = (0.5, 0.35, 0.65, 0.2, 0.8)
"""Fractions of a segment's length where a label may sit, in order of preference."""
GAP = 0.25
"""Clearance between a label's box and its segment, in text heights [-]."""


def label_box(text: str, insert: Sequence[float], height: float) -> tuple[float, float, float, float]:
    """Box (x0, y0, x1, y1) of ``text`` whose lower-left corner is ``insert`` [drawing units]."""
    x, y = float(insert[0]), float(insert[1])
    return x, y, x + CHAR_WIDTH * height * len(text), y + height


def overlap(a: Sequence[float], b: Sequence[float]) -> bool:
    """Whether two boxes (x0, y0, x1, y1) share interior area."""
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def place_labels(segments: Sequence[np.ndarray], texts: Sequence[str], height: float) -> list[tuple[float, float]]:
    """Lower-left corners of the labels, one per segment (see module doc).

    Parameters
    ----------
    segments : sequence of ndarray, each shape (n, 2)
        Polylines; a label goes beside the part from the first to the last point.
    texts : sequence of str
    height : float
        Text height (same units as the segments).

    Returns
    -------
    list of (float, float)
        Where each label's box starts. Where every candidate overlaps, the one overlapping
        the fewest labels placed before.
    """
    placed: list[tuple[float, float, float, float]] = []
    out = []
    for seg, text in zip(segments, texts, strict=True):
        seg = np.asarray(seg, float).reshape(-1, 2)
        a, b = seg[0], seg[-1]
        d = b - a
        length = float(np.hypot(*d))
        t = d / length if length > 0 else np.array([1.0, 0.0])
        n = np.array([-t[1], t[0]])
        w = CHAR_WIDTH * height * len(text)
        off = 0.5 * (abs(n[0]) * w + abs(n[1]) * height) + GAP * height
        best, best_hits = None, None
        for k in (1, 2, 3):
            for f in ALONG:
                for side in (1.0, -1.0):
                    c = a + f * d + side * k * off * n
                    corner = (float(c[0] - 0.5 * w), float(c[1] - 0.5 * height))
                    box = label_box(text, corner, height)
                    hits = sum(overlap(box, p) for p in placed)
                    if best_hits is None or hits < best_hits:
                        best, best_hits = corner, hits
                    if hits == 0:
                        break
                if best_hits == 0:
                    break
            if best_hits == 0:
                break
        placed.append(label_box(text, best, height))
        out.append(best)
    return out
