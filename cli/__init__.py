"""The ``pefsim`` command line: parses arguments, dispatches, and owns error reporting.

Each command lives in its own module ``cli/<name>.py`` exposing ``register(subparsers)``
(which adds the parser and sets ``func``). Commands import their heavy dependencies inside
``func`` so that ``pefsim --help`` and ``pefsim list`` start fast.

``pefsim`` alone prints the help, ``pefsim --version`` the installed version. Errors derived
from :class:`scenarios.PefsimError` become one line on stderr and exit code 2; anything else is
a bug and shows its traceback.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from typing import Any

from jit import compiled
from scenarios import PefsimError, PlanningError

COMMANDS = ("list", "map", "plan", "place", "run", "mc", "validate", "paper", "export", "watch", "worlds")

EXIT_OK, EXIT_CHECK_FAILED, EXIT_BAD_INPUT = 0, 1, 2

class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # argparse's own usage errors are bad input too
        self.exit(EXIT_BAD_INPUT, f"pefsim: error: {message}\n")


#: About how long each command's first run on a machine compiles its kernels [s] (numba's cache
#: empty): CPU seconds of a cold run less a warm one on a 2-core machine (numba compiles on one
#: thread), rounded up (docs/benchmarks.md). Said before the compilation starts.
COMPILE_SECONDS = {"map": 20, "plan": 15, "export": 15, "place": 45, "run": 30, "validate": 30, "mc": 30,
                   "watch": 20, "worlds": 30, "paper": 60}
COMPILE_SECONDS_DEFAULT = 30


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
    parser = _Parser(prog="pefsim", description="Robot routes planned from a Position Error Function (PEF), "
                                                "and checked in simulation. Each command takes --help.")
    parser.add_argument("--version", action="version", version=f"pefsim {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in COMMANDS:
        importlib.import_module(f"cli.{name}").register(sub)
    return parser


def _version() -> str:
    """Return the installed distribution's version (package metadata), or a note that it is not installed."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("pefsim")
    except PackageNotFoundError:
        return "(not installed: run pip install -e .)"


def _with_source(args: argparse.Namespace, exc: PefsimError) -> str:
    """Name the scenario in a planning error that does not (a plan or placement that failed on it)."""
    message, scenario = str(exc), getattr(args, "scenario", None)
    if not isinstance(exc, PlanningError) or not isinstance(scenario, str) or not scenario or scenario in message:
        return message
    return f"{scenario}: {message}"


def _show_warning(message, category, filename, lineno, file=None, line=None, _default=None) -> None:
    """Print pefsim's own warnings (:class:`scenarios.errors.ScenarioWarning`) as one line."""
    from scenarios.errors import ScenarioWarning

    if issubclass(category, ScenarioWarning):
        print(f"pefsim: warning: {message}", file=sys.stderr if file is None else file)
    else:
        _default(message, category, filename, lineno, file, line)


def main(argv: list[str] | None = None) -> int:
    import functools
    import warnings

    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:  # ``pefsim`` alone: what it can do
        parser.print_help()
        return EXIT_OK
    if not isinstance(warnings.showwarning, functools.partial):  # once per process
        warnings.showwarning = functools.partial(_show_warning, _default=warnings.showwarning)
    if argv is None:  # the program, not a caller in Python: a cold numba cache is said, before and after
        compiled.announce_compiles(COMPILE_SECONDS.get(args.command, COMPILE_SECONDS_DEFAULT))
    try:
        code = args.func(args)
        code = EXIT_OK if code is None else int(code)
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

