"""``pefsim paper``: reproduce the paper's claims as figures, numbers and verdicts on one HTML page."""

from __future__ import annotations

import argparse

DEFAULT_OUT = "paper-report"


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {value}")
    return value


def _claim_ids(text: str) -> set[int]:
    try:
        ids = {int(part) for part in text.split(",") if part.strip()}
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected claim numbers like 1,3,5, got {text!r}") from None
    if not ids or not ids <= set(range(1, 8)):
        raise argparse.ArgumentTypeError(f"expected claim numbers in 1..7, got {text!r}")
    return ids


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "paper", help="reproduce the paper's claims (figures, numbers, verdicts) as one HTML page",
        description="Reproduce the claims of the source paper: 1 area smallest at α = 90°, 2 ... and at "
                    "a = b, 3 more markers never increase the PEF, 4 markers beyond two cost more time than "
                    "they gain, 5 fault area nearly a parallelogram below 1 % error, 6 segment-area error "
                    "and GDOP grow together, 7 a planned route stays under ε_max in simulation. Each gets a "
                    "figure, its numbers and a verdict (holds / holds only when … / does not hold) computed "
                    "from them, on a self-contained page OUT/index.html (PNGs also in OUT/figures/, claim "
                    "7's Monte-Carlo sweep in OUT/mc/, completed rather than redone on a second call).")
    p.add_argument("--out", default=DEFAULT_OUT, help=f"output directory (default: {DEFAULT_OUT})")
    p.add_argument("--quick", action="store_true",
                   help="fewer samples, coarser grids and 3 Monte-Carlo runs instead of 10 "
                        "(seconds, for tests)")
    p.add_argument("--runs", type=_positive, help="Monte-Carlo runs of claim 7 (default 10, 3 with --quick)")
    p.add_argument("--workers", type=_positive, help="Monte-Carlo worker processes (default: CPU count)")
    p.add_argument("--claims", type=_claim_ids, metavar="LIST", help="only these claims, e.g. 1,3,5")
    p.add_argument("--no-sections", action="store_true",
                   help="skip the results beside the claims (redundancy against blocked lines of sight)")
    p.add_argument("--json", action="store_true",
                   help="print the claims (id, title, verdict, numbers) as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import pefsim
    from cli import print_json

    page = pefsim.paper(args.out, quick=args.quick, runs=args.runs, workers=args.workers, claims=args.claims,
                        sections=not args.no_sections)
    if args.json:
        print_json(page.to_dict())
        return 0
    for c in page.claims:
        print(f"{c.id}. {c.title}: {c.verdict}")
    for x in page.sections:
        print(f"beside the claims: {x.title} ({x.seconds:.0f} s)")
    print(f"report: {page.index} ({page.seconds:.0f} s)")
    return 0
