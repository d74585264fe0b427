"""The ``pefsim`` command line: parses arguments, dispatches, and owns error reporting.

Each command lives in its own module ``sim/cli/<name>.py`` exposing ``register(subparsers)``
(which adds the parser and sets ``func``). Commands import their heavy dependencies inside
``func`` so that ``pefsim --help`` and ``pefsim list`` start fast.

Errors derived from :class:`scenarios.PefsimError` become one line on stderr and exit code 2;
anything else is a bug and shows its traceback.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from typing import Any

from scenarios import PefsimError, PlanningError

COMMANDS = ("list", "map", "plan", "place", "run", "mc", "validate", "paper", "export", "compile", "worlds")

EXIT_OK, EXIT_CHECK_FAILED, EXIT_BAD_INPUT = 0, 1, 2

#: Commands whose process ends without the interpreter's teardown once they succeeded, when run
#: as the program (``argv`` None): freeing numba's and LLVM's objects module by module takes
#: ~0.4 s of CPU, a fifth of a whole ``map``. They write their files through closed handles and
#: start no process; a recording (``--rrd``) keeps the normal exit, as its writer may flush late.
QUICK_EXIT = ("map", "plan")


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # argparse's own usage errors are bad input too
        self.exit(EXIT_BAD_INPUT, f"pefsim: error: {message}\n")


def print_json(obj: Any) -> None:
    """Print ``obj`` as JSON on stdout (the machine-readable form of every summary)."""
    json.dump(obj, sys.stdout, indent=2, allow_nan=False, default=_jsonable)
    sys.stdout.write("\n")


def _jsonable(o: Any) -> Any:
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="pefsim", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name in COMMANDS:
        importlib.import_module(f"sim.cli.{name}").register(sub)
    return parser


def _quick_exit(code: int) -> None:
    """End the process now with ``code``: flush the standard streams, run the atexit handlers.

    Returns (and the caller exits normally) under a profiler or tracer (``cProfile``, coverage:
    they write their results at the normal exit), or while a thread other than the PEF kernels'
    idle pool is alive.
    """
    import atexit
    import os
    import threading

    if sys.getprofile() is not None or sys.gettrace() is not None:
        return
    main_thread = threading.main_thread()
    if any(t is not main_thread and not t.daemon and not t.name.startswith("pef-kernel")
           for t in threading.enumerate()):
        return
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (BrokenPipeError, ValueError):
        pass
    run_exitfuncs = getattr(atexit, "_run_exitfuncs", None)
    if run_exitfuncs is None:
        return
    run_exitfuncs()
    os._exit(code)


def _with_source(args: argparse.Namespace, exc: PefsimError) -> str:
    """Name the scenario in a planning error that does not (a plan or placement that failed on it)."""
    message, scenario = str(exc), getattr(args, "scenario", None)
    if not isinstance(exc, PlanningError) or not isinstance(scenario, str) or not scenario or scenario in message:
        return message
    return f"{scenario}: {message}"


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        code = args.func(args)
        code = EXIT_OK if code is None else int(code)
        if argv is None and args.command in QUICK_EXIT and not getattr(args, "rrd", None):
            _quick_exit(code)
    except PefsimError as exc:
        print(f"pefsim: error: {_with_source(args, exc)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("pefsim: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (``pefsim ... | head``): not an error of ours
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    return EXIT_OK if code is None else int(code)

