"""The paper report: one self-contained HTML page (figures embedded as base64) from the claims."""

from __future__ import annotations

import base64
import html
import os
from pathlib import Path
from typing import Any

from scenarios.errors import output_errors
from validation.paper.claims import DOES_NOT_HOLD, HOLDS, PAPER_RE, Claim, Options

PAPER_TITLE = "Trajectory Planning Based on Position Error Analysis and Fault Area Modelling"

_CSS = """
body { font-family: system-ui, sans-serif; max-width: 1180px; margin: 2em auto; padding: 0 1em;
       color: #222; }
h1 { font-size: 1.5em; }
h2 { font-size: 1.2em; margin-top: 2.2em; border-top: 1px solid #ccc; padding-top: 1em; }
blockquote { color: #555; border-left: 4px solid #ccc; margin: 0.5em 0; padding: 0.2em 1em;
             font-style: italic; }
table { border-collapse: collapse; font-size: 0.88em; margin: 0.6em 0; }
td, th { border: 1px solid #ddd; padding: 3px 8px; text-align: left; vertical-align: top; }
th { background: #f4f4f4; }
.v { font-weight: 600; padding: 2px 8px; border-radius: 4px; }
.holds { background: #d8f3dc; color: #1b4332; } .only { background: #fff3bf; color: #7a5900; }
.not { background: #ffd6d6; color: #7a0010; }
img { max-width: 100%; border: 1px solid #eee; }
code { background: #f4f4f4; padding: 0 3px; }
"""


def verdict_class(verdict: str) -> str:
    """CSS class of a verdict: ``holds``, ``only`` or ``not``."""
    return "holds" if verdict == HOLDS else "not" if verdict == DOES_NOT_HOLD else "only"


def _flatten(numbers: dict[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    rows = []
    for key, value in numbers.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            rows.extend(_flatten(value, f"{name}."))
        else:
            rows.append((name, value))
    return rows


def _value(v: Any) -> str:
    if isinstance(v, list):
        return ", ".join(_value(x) for x in v)
    if v is None:
        return "–"
    return f"{v:g}" if isinstance(v, float) else str(v)


def _claim_html(c: Claim) -> str:
    png = base64.b64encode(Path(c.figure).read_bytes()).decode("ascii")
    rows = "".join(f"<tr><td><code>{html.escape(k)}</code></td><td>{html.escape(_value(v))}</td></tr>"
                   for k, v in _flatten(c.numbers))
    return (f'<h2 id="claim{c.id}">Claim {c.id}: {html.escape(c.title)}</h2>\n'
            f"<blockquote>{html.escape(c.statement)}</blockquote>\n"
            f'<p>Verdict: <span class="v {verdict_class(c.verdict)}">{html.escape(c.verdict)}</span></p>\n'
            f'<img alt="claim {c.id} figure" src="data:image/png;base64,{png}">\n'
            f"<p>{html.escape(c.explanation)}</p>\n"
            f"<details open><summary>Numbers</summary><table><tr><th>quantity</th><th>value</th></tr>"
            f"{rows}</table></details>\n")


def _section_html(sec) -> str:
    png = base64.b64encode(Path(sec.figure).read_bytes()).decode("ascii")
    rows = "".join(f"<tr><td><code>{html.escape(k)}</code></td><td>{html.escape(_value(v))}</td></tr>"
                   for k, v in _flatten(sec.numbers))
    return (f'<h2 id="{html.escape(sec.key)}">Beside the claims: {html.escape(sec.title)}</h2>\n'
            f"<p><em>Not a claim of the paper.</em></p>\n"
            f'<img alt="{html.escape(sec.key)} figure" src="data:image/png;base64,{png}">\n'
            f"<p>{html.escape(sec.explanation)}</p>\n"
            f"<details open><summary>Numbers</summary><table><tr><th>quantity</th><th>value</th></tr>"
            f"{rows}</table></details>\n")


def render(claims: list[Claim], options: Options, seconds: float, sections=()) -> str:
    """Return the HTML page of the claims.

    Parameters
    ----------
    claims : list of Claim
        Reproduced claims, with their figures on disk.
    options : Options
        How they were computed (shown in the page).
    seconds : float
        Total wall time [s].
    sections : sequence of validation.paper.redundancy.Section
        Results shown after the claims (not claims of the paper).
    """
    summary = "".join(
        f'<tr><td><a href="#claim{c.id}">{c.id}</a></td><td>{html.escape(c.title)}</td>'
        f'<td><span class="v {verdict_class(c.verdict)}">{html.escape(c.verdict)}</span></td>'
        f"<td>{c.seconds:.1f} s</td></tr>" for c in claims)
    mode = "quick (fewer samples and runs)" if options.quick else "full"
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f"<title>pefsim paper report</title><style>{_CSS}</style></head><body>\n"
            f"<h1>pefsim: the paper's claims, reproduced</h1>\n"
            f"<p>Paper: <em>{PAPER_TITLE}</em>. Each claim below is computed, not asserted: the numbers "
            f"come from the exact fault area (polygon clipping of the range annuli), the linearised "
            f"strips, GDOP, the PEF of the planner or a PyBullet Monte-Carlo, and the verdict is a fixed "
            f"function of those numbers (<code>holds</code>, <code>holds only when …</code>, "
            f"<code>does not hold</code>). Range error bounds are ρ = Re·r + ρ0 with the paper's laser, "
            f"Re = 1 mm / 15 m = {PAPER_RE:.4g}; each claim states its ρ0.</p>\n"
            f"<p>Mode: {mode}; total {seconds:.1f} s. Reproduce with <code>pefsim paper"
            f"{' --quick' if options.quick else ''}</code>.</p>\n"
            f"<table><tr><th>#</th><th>claim</th><th>verdict</th><th>time</th></tr>{summary}</table>\n"
            + "".join(_claim_html(c) for c in claims) + "".join(_section_html(x) for x in sections)
            + "</body></html>\n")


def write_page(out_dir: str | Path, claims: list[Claim], options: Options, seconds: float,
               sections=()) -> Path:
    """Write ``out_dir/index.html`` (claims, then ``sections``) atomically and return its path."""
    path = Path(out_dir) / "index.html"
    tmp = path.with_suffix(".html.tmp")
    with output_errors(path, "write the report"):
        tmp.write_text(render(claims, options, seconds, sections), encoding="utf-8")
        os.replace(tmp, path)
    return path
