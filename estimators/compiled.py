"""Compiled kernels: numba only when needed, ahead-of-time code where built, never stale code.

Every kernel of pefsim is defined with :func:`njit` instead of ``numba.njit``. That returns a
:class:`Kernel`, which compiles nothing and does not import numba. Its first call picks the code:

- the **ahead-of-time** build (``pefsim compile``, :mod:`estimators.aot`) when the kernel was
  declared with ``aot=SIGNATURE`` and the build holds it for the sources it was built from;
- otherwise numba's JIT (:func:`jit`): numba is imported, every kernel becomes a numba
  dispatcher, and each module's names that held a :class:`Kernel` are rebound to its dispatcher,
  so a kernel compiled from then on finds its callees as numba functions, as it would have with
  ``numba.njit`` itself.

Why: importing numba and loading one cached kernel cost 1.4-2.0 s on our hosts (numba's
type registries, and scipy.linalg for its BLAS check), most of a whole ``pefsim map`` or
``plan`` on a big hall. With the ahead-of-time build those commands never import numba.

numba caches a compiled function beside its own source file (``cache=True``) and throws the
cache away when that file changes. A kernel that calls kernels of other files compiles their
code into its own, so after an edit of one of *those* files the caller's cache would still run
the old code. :func:`keep_fresh`, called at the end of a module that defines cached kernels,
keys each of them on the sources of every module whose kernels it reaches, or whose constants
it reads (found from the names its code uses, transitively): when their hash differs from the one stored beside the
cache, the kernel's cache is flushed, and numba compiles it afresh on first use. For a module of
:class:`Kernel` objects this happens in :func:`jit`, when they become dispatchers.

It costs one hash of a few source files per module. Where the cache directory cannot be written
numba does not cache either, and nothing is stored.
"""

from __future__ import annotations

import functools
import hashlib
import sys
import threading
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

_STAMP_SUFFIX = ".inlined"

_lock = threading.RLock()
_kernels: list[Kernel] = []
_fresh_pending: list[str] = []
_jitted = False


class Kernel:
    """A kernel defined with :func:`njit`, compiled on its first call.

    Calling it runs the ahead-of-time code when there is a fresh build of it, else numba's
    dispatcher (after :func:`jit`). Other attributes (``py_func``, ``signatures``, ...) are
    the dispatcher's, and reading them calls :func:`jit`.

    Attributes
    ----------
    py_func : callable
        The Python function.
    options : dict
        The ``numba.njit`` options.
    aot : str or None
        The numba signature it is built with ahead of time, or None (JIT only).
    """

    def __init__(self, py_func: Callable, options: dict, aot: str | None):
        self.py_func = py_func
        self.options = options
        self.aot = aot
        self._fn: Callable | None = None
        self._dispatcher: Any = None
        functools.update_wrapper(self, py_func)

    @property
    def key(self) -> str:
        """``module.qualname``: the name of the kernel in the ahead-of-time build."""
        return f"{self.py_func.__module__}.{self.py_func.__qualname__}"

    def __call__(self, *args):
        fn = self._fn
        if fn is None:
            fn = self.resolve()
        return fn(*args)

    def resolve(self) -> Callable:
        """Return the code a call runs: the ahead-of-time function, or numba's dispatcher."""
        with _lock:
            if self._fn is None:
                fn = None
                if self.aot is not None:
                    from estimators import aot

                    built = aot.function(self.key, self.aot)
                    if built is not None:
                        fn = _checked(built, *aot.array_arguments(self.key), self)
                if fn is None:
                    jit()
                    fn = self._dispatcher
                self._fn = fn
            return self._fn

    def __getattr__(self, name: str):
        if name.startswith("__") or name in ("_fn", "_dispatcher"):
            raise AttributeError(name)
        jit()
        return getattr(self._dispatcher, name)

    def __reduce__(self):
        return _by_name, (self.py_func.__module__, self.py_func.__qualname__)

    def __repr__(self) -> str:
        return f"<pefsim kernel {self.key}>"


def _checked(built: Callable, nargs: int, arrays: tuple, integers: tuple, kernel: Kernel) -> Callable:
    """``built``, called only with the arguments of its signature; numba's dispatcher for any others.

    The built code reads whatever array it is given as its signature's dtype and layout (an
    int64 array as float64, a strided view as contiguous, a list as memory: a crash; and it writes
    into a read-only array, where numba refuses to), so each call checks its arrays first (about
    0.3 us each), and that its integer arguments are integers (it would truncate a float). Other
    arguments (another dtype, layout, type or count) go to numba's dispatcher, which compiles for
    them, as ``numba.njit`` would.
    """
    import numpy as np

    wanted = tuple((i, np.dtype(dt), nd, c) for i, dt, nd, c in arrays)

    def call(*args):
        if len(args) == nargs:
            for i, dt, nd, contiguous in wanted:
                a = args[i]
                if type(a) is not np.ndarray or a.dtype != dt or a.ndim != nd or not a.flags.writeable or (
                        contiguous and not a.flags.c_contiguous):
                    break
            else:
                if all(isinstance(args[i], (int, np.integer)) for i in integers):
                    return built(*args)
        jit()
        return kernel._dispatcher(*args)

    return call


def _by_name(module: str, qualname: str):
    import importlib

    return getattr(importlib.import_module(module), qualname)


def njit(*args, aot: str | None = None, **options):
    """``numba.njit`` without numba until the kernel runs (see the module docstring).

    Parameters
    ----------
    aot : str, optional
        A numba signature (``"float64(float64[::1], int64)"``): the kernel is built ahead of time
        with it by ``pefsim compile``. The arrays a caller passes must match it (dtype, layout).
    **options
        ``numba.njit`` options (``cache``, ``nogil``, ``error_model``, ...).

    Returns
    -------
    Kernel, or numba's dispatcher once :func:`jit` has run.
    """
    def wrap(fn: Callable):
        with _lock:
            kernel = Kernel(fn, options, aot)
            _kernels.append(kernel)
            if _jitted:  # defined after jit(): its module gets the dispatcher, as the others did
                import numba

                kernel._dispatcher = numba.njit(**options)(fn)
                return kernel._dispatcher
            return kernel

    if args and callable(args[0]):
        return wrap(args[0])
    return wrap


def kernels() -> list[Kernel]:
    """Every :class:`Kernel` defined so far, in definition order."""
    return list(_kernels)


def jitted() -> bool:
    """Whether :func:`jit` has run in this process (numba imported, the kernels dispatchers)."""
    return _jitted


def jit() -> None:
    """Turn every :class:`Kernel` into a numba dispatcher, and every name bound to one into it.

    Runs once per process, on the first call of a kernel that has no ahead-of-time code. The
    :class:`Kernel` objects themselves stay callable (an ahead-of-time kernel keeps its code).
    """
    global _jitted
    with _lock:
        if _jitted:
            return
        import numba

        for k in _kernels:
            k._dispatcher = numba.njit(**k.options)(k.py_func)
        _jitted = True
        swap = {id(k): k._dispatcher for k in _kernels}
        # names of modules (ours, tests, scripts) that imported a kernel, as well as its own module
        for module in list(sys.modules.values()):
            names = getattr(module, "__dict__", None)
            if not isinstance(names, dict):
                continue
            for name, value in list(names.items()):
                if type(value) is Kernel:
                    names[name] = swap[id(value)]
        for name in _fresh_pending:
            _flush_stale(name)
        _fresh_pending.clear()


def _code_names(code: types.CodeType) -> set[str]:
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _code_names(const)
    return names


def _is_dispatcher(obj) -> bool:
    if "numba" not in sys.modules:
        return False
    from numba.core.registry import CPUDispatcher

    return isinstance(obj, CPUDispatcher)


def _callees(dispatcher) -> list:
    """Dispatchers named in a kernel's code: globals, and attributes of modules it uses."""
    fn = dispatcher.py_func
    names = _code_names(fn.__code__)
    found = []
    for name in names:
        obj = fn.__globals__.get(name)
        if _is_dispatcher(obj) or isinstance(obj, Kernel):
            found.append(obj)
        elif isinstance(obj, types.ModuleType):
            found += [a for a in (getattr(obj, n, None) for n in names) if _is_dispatcher(a) or isinstance(a, Kernel)]
    return found


#: top-level packages whose modules' constants a kernel may freeze into its code
_OWN_PACKAGES = ("estimators", "planner", "sim", "scenarios")


@functools.cache
def _installed_roots() -> tuple[str, ...]:
    import sysconfig

    return tuple({str(Path(sysconfig.get_path(k)).resolve()) for k in ("stdlib", "platstdlib", "purelib", "platlib")})


def _ours(module: types.ModuleType | None) -> bool:
    """Tell whether a module is ours or the user's (not the standard library, not an installed one).

    numpy's or numba's constants change only with their version, which numba's cache keys on.
    """
    name, path = getattr(module, "__name__", ""), getattr(module, "__file__", None)
    if not path:
        return False
    return name.split(".")[0] in _OWN_PACKAGES or not str(Path(path).resolve()).startswith(_installed_roots())


@functools.cache
def _imported_from(module_name: str) -> dict[str, str]:
    """``{name: module}`` of a module's ``from X import name`` statements (X one of :func:`_ours`)."""
    module = sys.modules.get(module_name)
    path = getattr(module, "__file__", None)
    out: dict[str, str] = {}
    if not path or not path.endswith(".py"):
        return out
    import ast
    import importlib.util

    for node in ast.walk(ast.parse(Path(path).read_bytes())):
        if isinstance(node, ast.ImportFrom):
            package = module.__package__ if node.level else None
            source = importlib.util.resolve_name("." * node.level + (node.module or ""), package)
            if _ours(sys.modules.get(source)):
                out.update({a.asname or a.name: source for a in node.names})
    return out


def _constant_sources(fn) -> set[Path]:
    """Files of our modules whose constants ``fn``'s code reads (numba freezes globals)."""
    files = set()
    imported = _imported_from(fn.__module__)
    for name in _code_names(fn.__code__):
        obj = fn.__globals__.get(name)
        source = None
        if isinstance(obj, types.ModuleType):
            source = obj
        elif name in imported:
            source = sys.modules.get(imported[name])
        if _ours(source):
            files.add(Path(source.__file__).resolve())
    return files


def inlined_sources(dispatcher) -> list[Path]:
    """Source files, other than its own, whose content ``dispatcher``'s compiled code holds, sorted.

    Those of every kernel it reaches, and those of the modules it or they read a constant from
    (``from estimators.measurements import _MIN_RANGE``, ``module.CONSTANT``): numba compiles a
    global's value into the code, so an edit there changes the code as an edit of a callee does.

    Parameters
    ----------
    dispatcher : numba.core.registry.CPUDispatcher or Kernel
        A ``numba.njit`` function, or a kernel of :func:`njit`.

    Returns
    -------
    list of pathlib.Path
    """
    own = Path(dispatcher.py_func.__code__.co_filename).resolve()
    seen, todo, files = {id(dispatcher.py_func)}, [dispatcher], set()
    while todo:
        current = todo.pop()
        files |= _constant_sources(current.py_func)
        for callee in _callees(current):
            if id(callee.py_func) not in seen:
                seen.add(id(callee.py_func))
                todo.append(callee)
                files.add(Path(callee.py_func.__code__.co_filename).resolve())
    files.discard(own)
    return sorted(files)


def _digest(files: list[Path]) -> str:
    h = hashlib.sha256()
    for f in files:
        h.update(str(f.name).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def keep_fresh(module_name: str) -> None:
    """Flush the cache of every cached kernel of a module whose inlined sources changed.

    Parameters
    ----------
    module_name : str
        ``__name__`` of the calling module (call it after the module's kernels are defined).
        Kernels of :func:`njit` are checked when they become numba dispatchers (:func:`jit`).
    """
    with _lock:
        if not _jitted and any(type(v) is Kernel for v in vars(sys.modules[module_name]).values()):
            _fresh_pending.append(module_name)
            return
    _flush_stale(module_name)


def _flush_stale(module_name: str) -> None:
    module = sys.modules[module_name]
    for obj in list(vars(module).values()):
        if not (_is_dispatcher(obj) and obj.__module__ == module_name):
            continue
        cache = getattr(obj, "_cache", None)
        files = inlined_sources(obj)
        if not files or cache is None or not hasattr(cache, "cache_path"):
            continue  # not cached, or inlines nothing: numba's own key is enough
        digest = _digest(files)
        stamp = Path(cache.cache_path) / f"{module_name}.{obj.py_func.__qualname__}{_STAMP_SUFFIX}"
        try:
            if stamp.read_text() == digest:
                continue
        except OSError:
            pass
        cache.flush()
        try:
            stamp.write_text(digest)
        except OSError:
            pass  # a read-only tree: numba cannot cache here either
