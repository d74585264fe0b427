"""Compiled kernels: numba only when needed, its on-disk cache, never stale code.

Every kernel of pefsim is defined with :func:`njit` instead of ``numba.njit``. That returns a
:class:`Kernel`, which compiles nothing and does not import numba. Its first call runs
:func:`jit`: numba is imported, every kernel becomes a numba dispatcher, and each module's names
that held a :class:`Kernel` are rebound to its dispatcher, so a kernel compiled from then on finds
its callees as numba functions, as it would have with ``numba.njit`` itself.

Why: importing numba and loading one cached kernel cost 1.4-2.0 s on our hosts (numba's
type registries, and scipy.linalg for its BLAS check); a command that runs no kernel (``pefsim
list``, ``--help``, reading a sweep's tables) should not pay it.

numba caches a compiled function (``cache=True``) under a stamp of its own source file and
compiles it afresh when that file changes. A kernel that calls kernels of other files compiles
their code into its own, and a global's value is frozen into the code, so after an edit of one of
*those* files numba's stamp would still match and the caller run the old code (numba's
documented limit: "cache invalidation fails to recognize changes in symbols defined in a different
file"). So each cached kernel is keyed on the sources of every module whose kernels it reaches, or
whose constants it reads (found from the names its code uses, transitively,
:func:`inlined_sources`): as it becomes a dispatcher, it gets numba's own cache locators with a
stamp that also holds the digest of those files (:mod:`jit.locators`, chosen through numba's
documented ``NUMBA_CACHE_LOCATOR_CLASSES`` setting, for that kernel only). When they change, numba
finds the stamp differs, compiles the kernel afresh and overwrites its entries in place. It costs
one hash of a few source files per kernel. :func:`keep_fresh` checks that a module holds no
``numba.njit`` function that inlines other files (numba alone would key it on its own file).

The first run on a machine compiles every kernel it calls (tens of seconds for a whole episode);
:func:`announce_compiles` makes a program say so on stderr as the first compilation starts (how
long it may take), and once more when it ends (how long it took).

Where the compiled code goes: numba's cache, ``__pycache__`` beside each kernel's source file
(numba's own fallback, a per-user folder, where that is not writable; ``NUMBA_CACHE_DIR`` where
set), one entry per kernel and argument types. Every command reads the same entries: a kernel
that ``place`` compiled is loaded, not compiled, by ``validate`` (each command compiles only the
kernels no command before it called).
"""

from __future__ import annotations

import atexit
import collections
import functools
import hashlib
import sys
import threading
import time
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

_lock = threading.RLock()
_kernels: list[Kernel] = []
_jitted = False
#: ids of the dispatchers of kernels with ``cache=True``
_cached: set[int] = set()
_timer = None  # the numba listener of _compile_timer, once jit() ran
_announce = False
_expect: float | None = None  # seconds the announcement before compiling states
_said_start = False
_worker_says = False  # a worker process that says the first line for its parent (announce_in_worker)


class Kernel:
    """A kernel defined with :func:`njit`, compiled on its first call.

    Calling it runs numba's dispatcher (after :func:`jit`). Other attributes (``signatures``,
    ...) are the dispatcher's, and reading them calls :func:`jit`.

    Attributes
    ----------
    py_func : callable
        The Python function.
    options : dict
        The ``numba.njit`` options.
    """

    def __init__(self, py_func: Callable, options: dict):
        self.py_func = py_func
        self.options = options
        self._fn: Callable | None = None
        self._dispatcher: Any = None
        functools.update_wrapper(self, py_func)

    @property
    def key(self) -> str:
        """``module.qualname`` of the kernel."""
        return f"{self.py_func.__module__}.{self.py_func.__qualname__}"

    def __call__(self, *args):
        fn = self._fn
        if fn is None:
            fn = self.resolve()
        return fn(*args)

    def resolve(self) -> Callable:
        """Return the code a call runs: numba's dispatcher (calls :func:`jit` the first time)."""
        with _lock:
            if self._fn is None:
                jit()
                self._fn = self._dispatcher
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


def _by_name(module: str, qualname: str):
    import importlib

    return getattr(importlib.import_module(module), qualname)


def njit(*args, **options):
    """``numba.njit`` without numba until the kernel runs (see the module docstring).

    Parameters
    ----------
    **options
        ``numba.njit`` options (``cache``, ``nogil``, ``error_model``, ...).

    Returns
    -------
    Kernel, or numba's dispatcher once :func:`jit` has run.
    """
    def wrap(fn: Callable):
        with _lock:
            kernel = Kernel(fn, options)
            _kernels.append(kernel)
            if _jitted:  # defined after jit(): its module gets the dispatcher, as the others did
                _dispatch(kernel)
                return kernel._dispatcher
            return kernel

    if args and callable(args[0]):
        return wrap(args[0])
    return wrap


def jit() -> None:
    """Turn every :class:`Kernel` into a numba dispatcher, and every name bound to one into it.

    Runs once per process, on the first call of a kernel. The :class:`Kernel` objects themselves
    stay callable (they call their dispatcher).
    """
    global _jitted, _timer
    with _lock:
        if _jitted:
            return
        from numba.core import event

        # numba announces each compilation it does (a cache miss) as this event, nested ones inside
        _timer = _compile_timer()
        event.register("numba:compile", _timer)
        for k in _kernels:
            _dispatch(k)
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


def _dispatch(kernel: Kernel) -> None:
    import numba

    if not kernel.options.get("cache"):
        kernel._dispatcher = numba.njit(**kernel.options)(kernel.py_func)
        return
    from jit import locators

    files = inlined_sources(kernel)
    if files:
        locators.inlined[kernel.py_func] = _digest(files)
    # numba picks the locator as the dispatcher enables caching; only this kernel gets ours
    configured = numba.config.CACHE_LOCATOR_CLASSES
    numba.config.CACHE_LOCATOR_CLASSES = locators.classes(configured)
    try:
        kernel._dispatcher = numba.njit(**kernel.options)(kernel.py_func)
    finally:
        numba.config.CACHE_LOCATOR_CLASSES = configured
    _cached.add(id(kernel._dispatcher))


def _compile_timer():
    """Make a numba event listener that adds up the seconds numba spends compiling our cached kernels.

    Only the outermost compilation counts (a kernel compiles its callees inside its own); numba
    compiles under one global lock, so the events of two threads do not interleave. A kernel
    numba does not cache, or someone else's, compiles on every run and is not counted.
    """
    from numba.core import event

    class CompileTimer(event.Listener):
        def __init__(self):
            self.seconds = 0.0
            self._depth = 0
            self._t0 = 0.0

        def on_start(self, event) -> None:
            if self._depth == 0:
                if id(event.data["dispatcher"]) not in _cached:
                    return
                _say_compiling()
                self._t0 = time.perf_counter()
            self._depth += 1

        def on_end(self, event) -> None:
            if self._depth == 0:
                return
            self._depth -= 1
            if self._depth == 0:
                self.seconds += time.perf_counter() - self._t0

    return CompileTimer()


def compile_seconds() -> float:
    """Seconds this process spent compiling cached kernels of :func:`njit` (0.0 on a warm cache)."""
    return 0.0 if _timer is None else _timer.seconds


def announce_compiles(expect: float | None = None) -> None:
    """Make the program say on stderr that it compiles the kernels: as it starts, and how long it took at exit.

    The first line comes as numba starts the first compilation of a cached kernel (a cold cache),
    before the seconds of silence; the second when the program ends. Nothing is said where every
    kernel came from numba's cache, nor by a worker process.

    Parameters
    ----------
    expect : float, optional
        About how many seconds the compilation takes (the first line states it when given).
    """
    global _announce, _expect
    with _lock:
        if expect is not None:
            _expect = float(expect)
        if not _announce:
            _announce = True
            atexit.register(_say_compiled)


def announce_state() -> tuple | None:
    """Return what a worker process needs to say the first line of :func:`announce_compiles` for this one.

    None where this process says nothing, or has said it already (its estimate covered the
    command). Pass it to :func:`announce_in_worker` in the worker.
    """
    with _lock:
        return (_expect,) if _announce and not _said_start else None


def announce_in_worker(state: tuple | None) -> None:
    """In a worker process: say the line before the first compilation, as its parent would have.

    A pool's workers compile the kernels the parent never called (an episode's); without this a
    cold first ``validate --workers N`` compiles in silence. Each worker says it once; the line
    at exit stays the parent's.

    Parameters
    ----------
    state : tuple or None
        :func:`announce_state` of the parent (None: say nothing).
    """
    global _announce, _expect, _worker_says
    if state is None:
        return
    with _lock:
        _announce, _expect, _worker_says = True, state[0], True


def _say_compiling() -> None:
    """Say the line before the first compilation (:func:`announce_compiles`), once, in the main process only.

    Or in a worker that says it for its parent (:func:`announce_in_worker`).
    """
    global _said_start
    if not _announce or _said_start:
        return
    _said_start = True
    import multiprocessing

    if multiprocessing.parent_process() is not None and not _worker_says:
        return
    about = "" if _expect is None else f", about {_expect:.0f} s"
    who = "a worker is compiling" if _worker_says else "compiling"
    print(f"pefsim: {who} the kernels once{about}; numba caches them for later runs", file=sys.stderr,
          flush=True)


def _say_compiled() -> None:
    import multiprocessing

    if compile_seconds() > 0.0 and multiprocessing.parent_process() is None:
        print(f"pefsim: compiled the kernels once ({_timer.seconds:.0f} s); later runs use numba's cache",
              file=sys.stderr)


def _code_names(code: types.CodeType) -> set[str]:
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _code_names(const)
    return names


def _is_dispatcher(obj) -> bool:
    if "numba" not in sys.modules:
        return False
    from numba.extending import is_jitted

    return is_jitted(obj)


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
_OWN_PACKAGES = ("jit", "estimators", "planner", "sim", "scenarios")


@functools.cache
def _installed_roots() -> tuple[str, ...]:
    import sysconfig

    return tuple({str(Path(sysconfig.get_path(k)).resolve()) for k in ("stdlib", "platstdlib", "purelib", "platlib")})


def _ours(module: types.ModuleType | None) -> bool:
    """Tell whether a module is ours or the user's (not the standard library, not an installed one).

    numpy's or numba's constants change only with their version, which numba's cache keys on.
    """
    name, path = getattr(module, "__name__", ""), getattr(module, "__file__", None)
    return bool(path) and _ours_at(name, path)


@functools.cache
def _ours_at(name: str, path: str) -> bool:
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

    # the module's own statements (and those under if / try / with), not function bodies: an
    # import inside a function binds a local name, never a global a kernel could read
    todo = collections.deque(ast.parse(Path(path).read_bytes()).body)  # in ast.walk's order
    while todo:
        node = todo.popleft()
        if isinstance(node, (ast.If, ast.Try, ast.With)):
            todo += [*node.body, *getattr(node, "orelse", []), *getattr(node, "finalbody", []),
                     *(h for handler in getattr(node, "handlers", []) for h in handler.body)]
            continue
        if isinstance(node, ast.ImportFrom):
            package = module.__package__ if node.level else None
            source = importlib.util.resolve_name("." * node.level + (node.module or ""), package)
            if _ours(sys.modules.get(source)):
                out.update({a.asname or a.name: source for a in node.names})
    return out


def _constant_sources(fn) -> set[Path]:
    """Files of our modules whose constants ``fn``'s code reads (numba freezes globals)."""
    files = set()
    values = {name: fn.__globals__.get(name) for name in _code_names(fn.__code__)}
    # a module or a kernel is found without the import statements (a kernel's file counts as a
    # callee's); only another global may be a constant imported from one of our modules
    imports = any(v is not None and not isinstance(v, (types.ModuleType, Kernel)) and not _is_dispatcher(v)
                  for v in values.values())
    imported = _imported_from(fn.__module__) if imports else {}
    for name, obj in values.items():
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
    dispatcher : numba dispatcher (``numba.extending.is_jitted``) or Kernel
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
        h.update(_file_hash(f, *_stat(f)))
    return h.hexdigest()


def _stat(f: Path) -> tuple[int, int]:
    st = f.stat()
    return st.st_mtime_ns, st.st_size


@functools.cache
def _file_hash(f: Path, mtime_ns: int, size: int) -> bytes:
    # keyed on the stat too: a file edited while the process runs is hashed again
    return hashlib.sha256(f.read_bytes()).digest()


def keep_fresh(module_name: str) -> None:
    """Check that no ``numba.njit`` function of a module inlines other files.

    Kernels of :func:`njit` are keyed on every source they inline as they become numba
    dispatchers; a function of ``numba.njit`` itself would be keyed by numba on its own file only.

    Parameters
    ----------
    module_name : str
        ``__name__`` of the calling module (call it after the module's kernels are defined).

    Raises
    ------
    TypeError
        Where a ``numba.njit`` function of the module inlines kernels or constants of other files.
    """
    for name, obj in list(vars(sys.modules[module_name]).items()):
        if not (_is_dispatcher(obj) and obj.__module__ == module_name) or id(obj) in _dispatchers():
            continue
        files = inlined_sources(obj)
        if files:
            raise TypeError(f"{module_name}.{name} is a numba.njit function that inlines "
                            f"{', '.join(f.name for f in files)}; numba keys its cache on its own file only: "
                            f"define it with jit.compiled.njit")


def _dispatchers() -> set[int]:
    """Return the ids of the numba dispatchers of :func:`njit`'s kernels."""
    with _lock:
        return {id(k._dispatcher) for k in _kernels if k._dispatcher is not None}
