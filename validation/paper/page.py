"""The paper page: every claim (and the results beside them) reproduced and written as one HTML page."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from validation.paper.claims import Claim, Options
from validation.paper.html import write_page
from validation.paper.redundancy import Section, reproduce_redundancy
from validation.paper.reproduce import reproduce


@dataclass(frozen=True)
class PaperPage:
    """What :func:`reproduce_page` wrote.

    Attributes
    ----------
    out : Path
        The output directory.
    index : Path
        The page, ``out/index.html``.
    claims : list of Claim
        The claims reproduced, in order (each with its verdict, numbers and figure).
    sections : list of Section
        The results shown beside the claims.
    seconds : float
        Wall time of the whole reproduction [s].
    options : Options
        The sample sizes used.
    """

    out: Path
    index: Path
    claims: list[Claim]
    sections: list[Section] = field(default_factory=list)
    seconds: float = 0.0
    options: Options = field(default_factory=Options)

    def to_dict(self) -> dict:
        """Return the page as a JSON-ready dict (what ``pefsim paper --json`` prints; seconds to 0.1 s)."""
        return {"out": str(self.out), "index": str(self.index), "quick": self.options.quick,
                "seconds": round(self.seconds, 1), "claims": [c.to_dict() for c in self.claims],
                "sections": [x.to_dict() for x in self.sections]}


def reproduce_page(out_dir: str | Path, options: Options | None = None, only: set[int] | None = None,
                   sections: bool = True) -> PaperPage:
    """Reproduce the claims (``only`` these ids, default all) and write ``out_dir/index.html``.

    Parameters
    ----------
    out_dir : str or path
        Output directory (figures in ``figures/``, claim 7's sweep in ``mc/``).
    options : Options, optional
        Sample sizes; default the full run.
    only : set of int, optional
        Claim ids 1..7 to reproduce; default all.
    sections : bool
        Also the results beside the claims (only when every claim is reproduced).

    Returns
    -------
    PaperPage
    """
    options = options or Options()
    out = Path(out_dir)
    start = time.perf_counter()
    claims = reproduce(out, options, only=only)
    beside = [reproduce_redundancy(out, options)] if only is None and sections else []
    seconds = time.perf_counter() - start
    index = write_page(out, claims, options, seconds, beside)
    return PaperPage(out=out, index=index, claims=claims, sections=beside, seconds=seconds, options=options)
