"""``pefsim compile``: build the planner's kernels ahead of time (:mod:`estimators.aot`).

With the build, ``pefsim map`` and ``pefsim plan`` run their kernels without importing numba or
loading its cache, 1.4-2.0 s of each command; every other kernel still runs numba's JIT. The
build is kept beside the ``estimators`` package and used only while it matches the sources it
was built from, so ``pefsim compile`` is run again after an edit of a kernel (it rebuilds only
then). It needs the C compiler that Python extensions need; without one it says so in one line and
exits 0, as pefsim works without the build.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
import time
import warnings

#: packages whose modules define the kernels (importing them all registers every kernel)
PACKAGES = ("estimators", "planner")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("compile", help="build the planner's kernels ahead of time (fast map and plan)")
    p.add_argument("--check", action="store_true",
                   help="only report whether the build is there and fresh (exit 1 if not)")
    p.add_argument("--force", action="store_true", help="rebuild even if the build is fresh")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run)


def all_kernels() -> list:
    """Import every module of :data:`PACKAGES` and return every kernel they define."""
    from estimators import aot, compiled

    for pkg in PACKAGES:
        base = importlib.import_module(pkg)
        for info in pkgutil.walk_packages(base.__path__, prefix=pkg + "."):
            if not info.name.endswith("." + aot.NAME):  # the build itself is loaded by estimators.aot only
                importlib.import_module(info.name)
    return compiled.kernels()


def run(args: argparse.Namespace) -> int:
    from estimators import aot, compiled
    from sim.cli import print_json

    kernels = all_kernels()
    status = aot.status(kernels)
    fresh = all(v == "built" for v in status.values())
    summary = {"library": str(aot.library_path()), "kernels": status, "fresh": fresh, "built_s": None}
    if args.check or (fresh and not args.force):
        if args.json:
            print_json(summary)
        else:
            stale = sorted(k for k, v in status.items() if v != "built")
            print(f"{len(status)} kernels built ahead of time: " + ("all fresh" if fresh else
                  f"{len(stale)} missing or stale ({', '.join(stale)}); run pefsim compile"))
        return 0 if fresh or not args.check else 1
    t0 = time.perf_counter()
    compiled.jit()
    with warnings.catch_warnings():
        # pycc is numba's ahead-of-time compiler; its pending deprecation is numba's to resolve
        warnings.simplefilter("ignore")
        try:
            manifest = aot.build(kernels)
        except Exception as exc:  # the C toolchain's errors come in many types
            # not fatal: every kernel still runs through numba's JIT, only map and plan start slower,
            # so the README's "pefsim compile && pefsim mc ..." goes on without a compiler
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            print(f"pefsim: warning: compile: {first}; the kernels keep running through numba's JIT "
                  "(map and plan start 1-2 s slower)", file=sys.stderr)
            return 0
    summary.update(kernels={k: "built" for k in manifest["kernels"]}, fresh=True,
                   built_s=round(time.perf_counter() - t0, 1))
    if args.json:
        print_json(summary)
    else:
        print(f"compiled {len(manifest['kernels'])} kernels into {summary['library']} in {summary['built_s']} s")
    return 0
