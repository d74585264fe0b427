"""The ahead-of-time build of the kernels declared ``compiled.njit(aot=SIGNATURE)``.

``pefsim compile`` (:func:`build`) compiles them with numba's ``pycc`` into one extension module
beside this file, ``_aot_kernels`` (``.so``/``.pyd``), and writes ``_aot_kernels.json``: for
each kernel its signature, the source files its code comes from (its own and those of every
kernel it inlines, :func:`estimators.compiled.inlined_sources`) and their hash. The extension
needs numpy only: a command whose kernels are all in it never imports numba.

:func:`function` hands a kernel its built code only if the build is *fresh* for it: the same
signature, and the same bytes in each of its source files. An edited kernel, or one of its
callees, runs numba's JIT (correct, only slower to start) until the next ``pefsim compile``.
``PEFSIM_AOT=0`` in the environment ignores the build.

Each kernel is built with its own numba options (``nogil`` releases the GIL, as the threads of
:mod:`planner.pef.threads` need; ``error_model``, ``fastmath``), so it computes what the JIT
computes. The build targets the host's CPU, as numba's JIT does: kernels with
``fastmath={"contract"}`` (:mod:`planner.pef.pairs`) fuse multiply-adds where the CPU has FMA, and
code for the generic CPU family would round differently (another map on warehouse-reflectors).
A build is therefore for the machine that made it: the manifest records the CPU (``cpu``, LLVM's
name, for people; ``host``, :func:`host_fingerprint`, checked at load), and a build made on
another CPU is ignored (the JIT runs) until ``pefsim compile`` is run on this one.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.util
import json
import os
import platform
import shutil
import sys
import sysconfig
import tempfile
from pathlib import Path

NAME = "_aot_kernels"
HERE = Path(__file__).resolve().parent
#: paths in the manifest are relative to the folder that holds the packages
ROOT = HERE.parent

_state: tuple | None = None  # (module or None, manifest dict)
_file_hashes: dict[str, str] = {}


def library_path(folder: Path = HERE) -> Path:
    """Return the extension module's file in ``folder``."""
    return folder / (NAME + sysconfig.get_config_var("EXT_SUFFIX"))


def manifest_path(folder: Path = HERE) -> Path:
    """Return the manifest's file in ``folder``."""
    return folder / (NAME + ".json")


def _hash_file(rel: str) -> str | None:
    if rel not in _file_hashes:
        try:
            _file_hashes[rel] = hashlib.sha256((ROOT / rel).read_bytes()).hexdigest()
        except OSError:
            return None
    return _file_hashes[rel]


def sources_digest(files: list[str]) -> str | None:
    """Hash of the files (paths relative to :data:`ROOT`), None if one cannot be read."""
    h = hashlib.sha256()
    for rel in files:
        fh = _hash_file(rel)
        if fh is None:
            return None
        h.update(rel.encode())
        h.update(fh.encode())
    return h.hexdigest()


def host_fingerprint() -> str:
    """Return a short hash of this machine's CPU model and instruction set, without numba.

    LLVM's host CPU name (what the build targets) costs 0.24 s of importing llvmlite; the CPU's
    model and feature flags from ``/proc/cpuinfo`` (Linux) identify the same instructions in
    0.2 ms. Elsewhere the machine and processor names from :mod:`platform` stand in.
    """
    text = ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            text = f.read()
    except OSError:
        pass
    keep = []
    for line in text.splitlines():
        key, _, value = line.partition(":")
        key = key.strip()
        if key in ("vendor_id", "model name", "flags", "Features", "CPU implementer", "CPU part"):
            keep.append(f"{key}={' '.join(sorted(value.split()))}")
        elif not line.strip() and keep:
            break  # the first processor describes them all (the flags pefsim's code may use)
    if not keep:
        keep = [platform.machine(), platform.processor()]
    return hashlib.sha256("\n".join(keep).encode()).hexdigest()[:16]


def _load() -> tuple:
    global _state
    if _state is None:
        module, manifest = None, {}
        if os.environ.get("PEFSIM_AOT", "1") != "0":
            try:
                manifest = json.loads(manifest_path().read_text())
                if manifest.get("host") != host_fingerprint():
                    raise ValueError("built for another CPU")  # its instructions may not run here
                # as the submodule it is, so that importing estimators._aot_kernels finds this one
                name = f"{__package__}.{NAME}"
                module = sys.modules.get(name)
                if module is None:
                    path = library_path()
                    loader = importlib.machinery.ExtensionFileLoader(name, str(path))
                    spec = importlib.util.spec_from_file_location(name, path, loader=loader)
                    module = importlib.util.module_from_spec(spec)
                    loader.exec_module(module)
                    sys.modules[name] = module
            except (OSError, ValueError, ImportError):
                module, manifest = None, {}  # not built, or built for another Python or numpy
        _state = (module, manifest)
    return _state


def function(key: str, signature: str):
    """Return the built code of kernel ``key``, or None if the build is not fresh for it.

    Parameters
    ----------
    key : str
        The kernel's ``module.qualname``.
    signature : str
        Its declared ``aot`` signature.

    Returns
    -------
    callable or None
    """
    module, manifest = _load()
    entry = manifest.get("kernels", {}).get(key)
    if module is None or entry is None or entry.get("signature") != signature:
        return None
    if sources_digest(entry["files"]) != entry["digest"]:
        return None
    return getattr(module, entry["symbol"], None)


def array_arguments(key: str) -> tuple[int, tuple[tuple[int, str, int, bool], ...], tuple[int, ...]]:
    """Return the argument count, the array arguments and the positions of the integer ones.

    An array argument is (position, dtype, ndim, C-contiguous).

    The built code does not check what it is given (another dtype or layout would be read as if
    it were the signature's, a float for an integer truncated): :mod:`estimators.compiled`
    checks the arguments before each call.
    """
    entry = _load()[1]["kernels"][key]
    arrays = tuple((int(i), str(dt), int(nd), bool(c)) for i, dt, nd, c in entry["arrays"])
    return entry["nargs"], arrays, tuple(int(i) for i in entry["integers"])


def _describe_arguments(signature: str) -> tuple[int, list, list]:
    from numba.core import sigutils, types
    from numba.np.numpy_support import as_dtype

    args, _ = sigutils.normalize_signature(signature)
    arrays = [[i, str(as_dtype(t.dtype)), t.ndim, t.layout == "C"] for i, t in enumerate(args)
              if isinstance(t, types.Array)]
    integers = [i for i, t in enumerate(args) if isinstance(t, types.Integer)]
    return len(args), arrays, integers


def status(kernels) -> dict[str, str]:
    """For each kernel with an ``aot`` signature: ``"built"``, ``"stale"`` or ``"missing"``."""
    module, manifest = _load()
    out = {}
    for k in kernels:
        if k.aot is None:
            continue
        entry = manifest.get("kernels", {}).get(k.key)
        if module is None or entry is None:
            out[k.key] = "missing"
        else:
            out[k.key] = "built" if function(k.key, k.aot) is not None else "stale"
    return out


def _relative(path: Path) -> str:
    return path.resolve().relative_to(ROOT).as_posix()


def _flags_of_each_kernel(by_function: dict) -> None:
    """Make pycc compile each exported kernel with its own numba options (its ``@njit(...)``).

    pycc compiles every export with default flags: the GIL held, the python error model. This
    wraps its call of ``compile_extra`` to start from the kernel's own flags instead.
    """
    import numba.pycc.compiler as pycc_compiler
    from numba.core.compiler import Flags
    from numba.core.registry import cpu_target

    original = pycc_compiler.compile_extra

    def compile_extra(typing_context, target_context, func, args, return_type, flags, locals, library):
        own = Flags()
        cpu_target.options.parse_as_flags(own, by_function[func].targetoptions)
        for name in ("no_compile", "no_cpython_wrapper", "no_cfunc_wrapper", "nrt"):
            setattr(own, name, getattr(flags, name))
        return original(typing_context, target_context, func, args, return_type, own, locals=locals,
                        library=library)

    pycc_compiler.compile_extra = compile_extra


def build(kernels, folder: Path = HERE) -> dict:
    """Compile the kernels with an ``aot`` signature into ``folder`` (see the module docstring).

    Parameters
    ----------
    kernels : list of estimators.compiled.Kernel
        Every kernel defined (those without ``aot`` are skipped); :func:`estimators.compiled.jit`
        must have run, so their callees are numba dispatchers.
    folder : pathlib.Path
        Where the extension module and its manifest go (written last, each replaced at once).

    Returns
    -------
    dict
        The manifest.
    """
    import numba
    from numba.pycc import CC

    from estimators import compiled

    chosen = [k for k in kernels if k.aot is not None]
    entries, by_function = {}, {}
    for k in chosen:
        # and the two files that decide what a build holds: a change there may change every entry
        files = [_relative(Path(k.py_func.__code__.co_filename))] + [
            _relative(p) for p in compiled.inlined_sources(k._dispatcher)] + [
            _relative(Path(__file__)), _relative(Path(compiled.__file__))]
        symbol = k.key.replace(".", "__")
        nargs, arrays, integers = _describe_arguments(k.aot)
        entries[k.key] = {"symbol": symbol, "signature": k.aot, "files": files, "nargs": nargs, "arrays": arrays,
                          "integers": integers}
        by_function[k.py_func] = k._dispatcher
    _flags_of_each_kernel(by_function)
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="pefsim-aot-") as tmp:
        cc = CC(NAME)
        cc.output_dir = tmp
        cc.target_cpu = "host"  # the JIT's instructions (FMA under fastmath contract), its rounding
        for k in chosen:
            cc.export(entries[k.key]["symbol"], k.aot)(k.py_func)
        cc.compile()
        for e in entries.values():
            e["digest"] = sources_digest(e["files"])
        from llvmlite import binding

        manifest = {"numba": numba.__version__, "python": sys.version.split()[0],
                    "cpu": binding.get_host_cpu_name(), "host": host_fingerprint(), "kernels": entries}
        built = Path(tmp) / library_path(Path(tmp)).name
        # replace, never overwrite in place: a running process may have the old library mapped
        tmp_lib = folder / (built.name + ".new")
        shutil.copyfile(built, tmp_lib)
        os.replace(tmp_lib, library_path(folder))
        tmp_manifest = manifest_path(folder).with_suffix(".json.new")
        tmp_manifest.write_text(json.dumps(manifest, indent=1) + "\n")
        os.replace(tmp_manifest, manifest_path(folder))
    return manifest
