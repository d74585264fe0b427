"""numba's on-disk cache, keyed on every source a kernel compiles in.

numba caches a compiled function beside its own source file (``cache=True``) and throws the
cache away when that file changes. A kernel that calls kernels of other files compiles their
code into its own, so after an edit of one of *those* files the caller's cache would still run
the old code. :func:`keep_fresh`, called at the end of a module that defines cached kernels,
keys each of them on the sources of every module whose kernels it reaches (found from the
names its code uses, transitively): when their hash differs from the one stored beside the
cache, the kernel's cache is flushed, and numba compiles it afresh on first use.

It costs one hash of a few source files per import. Where the cache directory cannot be
written numba does not cache either, and nothing is stored.
"""

from __future__ import annotations

import hashlib
import sys
import types
from pathlib import Path

from numba.core.registry import CPUDispatcher

_STAMP_SUFFIX = ".inlined"


def _code_names(code: types.CodeType) -> set[str]:
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _code_names(const)
    return names


def _callees(dispatcher: CPUDispatcher) -> list[CPUDispatcher]:
    """Dispatchers named in a kernel's code: globals, and attributes of modules it uses."""
    fn = dispatcher.py_func
    names = _code_names(fn.__code__)
    found = []
    for name in names:
        obj = fn.__globals__.get(name)
        if isinstance(obj, CPUDispatcher):
            found.append(obj)
        elif isinstance(obj, types.ModuleType):
            found += [a for a in (getattr(obj, n, None) for n in names) if isinstance(a, CPUDispatcher)]
    return found


def inlined_sources(dispatcher: CPUDispatcher) -> list[Path]:
    """Source files of every kernel ``dispatcher`` reaches, other than its own, sorted.

    Parameters
    ----------
    dispatcher : numba.core.registry.CPUDispatcher
        A ``numba.njit`` function.

    Returns
    -------
    list of pathlib.Path
    """
    own = Path(dispatcher.py_func.__code__.co_filename).resolve()
    seen, todo, files = {id(dispatcher)}, [dispatcher], set()
    while todo:
        for callee in _callees(todo.pop()):
            if id(callee) not in seen:
                seen.add(id(callee))
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
    """
    module = sys.modules[module_name]
    for obj in list(vars(module).values()):
        if not (isinstance(obj, CPUDispatcher) and obj.__module__ == module_name):
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
