"""numba's cache locators, with a source stamp that covers the files a kernel inlines.

A numba cache locator says where a function's cache lives and stamps its freshness: numba
stores the stamp in the cache's index and ignores the index when the stamp differs, so the
function is compiled afresh and the index rewritten in place (its data files are numbered and
overwritten, so nothing piles up). numba's own stamp is the hash of the function's source file
only. Each class here is one of numba's locators (same place: ``NUMBA_CACHE_DIR`` where set,
``__pycache__`` beside the source, the per-user folder where that is not writable, ...) whose
stamp also holds the digest that :mod:`jit.compiled` put in :data:`inlined` for the function:
the sources of the other files whose kernels or constants its compiled code holds.

numba picks locators from ``numba.config.CACHE_LOCATOR_CLASSES`` (the documented
``NUMBA_CACHE_LOCATOR_CLASSES``, which accepts "custom locator classes ... using their full module
path") as a dispatcher enables caching; :func:`jit.compiled.njit` sets it to :func:`classes` for
that moment only, so no other numba function of the process is touched. A function without an
entry in :data:`inlined` keeps numba's own stamp, and thus its cache.
"""

from __future__ import annotations

from numba.core import caching

#: the digest of the files a function inlines, by function (filled by :mod:`jit.compiled`)
inlined: dict = {}

#: numba's default locator order (``CacheImpl``'s, as its documentation of ``NUMBA_CACHE_DIR`` states it)
NUMBA_DEFAULT = ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator", "IPythonCacheLocator",
                 "ZipCacheLocator")


class _InlinedStamp:
    """Mix-in: the stamp of numba's locator, and the digest of the sources the function inlines."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        self._inlined = inlined.get(py_func)

    def get_source_stamp(self):
        own = super().get_source_stamp()
        return own if self._inlined is None else (own, self._inlined)


class UserProvidedCacheLocator(_InlinedStamp, caching.UserProvidedCacheLocator):
    """numba's ``NUMBA_CACHE_DIR`` locator, stamped with the inlined sources too."""


class InTreeCacheLocator(_InlinedStamp, caching.InTreeCacheLocator):
    """numba's ``__pycache__`` locator, stamped with the inlined sources too."""


class UserWideCacheLocator(_InlinedStamp, caching.UserWideCacheLocator):
    """numba's per-user locator (a read-only tree), stamped with the inlined sources too."""


class IPythonCacheLocator(_InlinedStamp, caching.IPythonCacheLocator):
    """numba's IPython locator, stamped with the inlined sources too."""


class ZipCacheLocator(_InlinedStamp, caching.ZipCacheLocator):
    """numba's locator for a zipped package, stamped with the inlined sources too."""


_OURS = {name: f"{__name__}.{name}" for name in NUMBA_DEFAULT}


def classes(configured: str) -> str:
    """Return the value of ``numba.config.CACHE_LOCATOR_CLASSES`` for a kernel of :func:`jit.compiled.njit`.

    Parameters
    ----------
    configured : str
        The value in force (``NUMBA_CACHE_LOCATOR_CLASSES``; empty: numba's default order).

    Returns
    -------
    str
        The same locators, in the same order, as the classes of this module; a class numba does
        not ship (the user's own) stays as it is.
    """
    names = [n.strip() for n in configured.split(",") if n.strip()] or list(NUMBA_DEFAULT)
    out = []
    for name in names:
        short = name.removeprefix(f"{caching.__name__}.")
        out.append(_OURS.get(short, name))
    return ",".join(out)
