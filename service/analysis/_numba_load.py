"""Loading numba's cached kernels without building its compiler first.

numba's ``Cache.load_overload`` refreshes the whole target context before it reads a cached
kernel: it imports and registers every lowering numba has (numpy, linalg, random, typed
containers...), ~0.2 s CPU per process, although a kernel read from the cache is finished
machine code that needs none of it. What such a kernel does need is numba's runtime (NRT:
allocation of the arrays it returns), which is initialised here before the load. Compiling
(a cache miss) refreshes the context itself (``compiler.compile_extra``), and a cached
object-mode function gets the full refresh after it is read, as before; so nothing changes but
when the registries are built.

:func:`install` is called by the kernel modules (``import numba`` is already paid there). It
applies only to the numba versions it was checked against (:data:`CHECKED`); elsewhere, or
with ``SNAPWARN_NUMBA_FULL_REFRESH=1``, numba is left as it is.
"""

from __future__ import annotations

import os

#: numba versions whose ``Cache.load_overload`` this replaces (its body is unchanged from 0.49 to
#: 0.68, the version installed when this was written)
CHECKED = ("0.6",)

_installed = False


def install() -> bool:
    """Make numba load cached kernels with its runtime only; returns whether it applies."""
    global _installed
    if _installed:
        return True
    if os.environ.get("SNAPWARN_NUMBA_FULL_REFRESH", "") not in ("", "0"):
        return False
    import numba
    from numba.core import caching
    from numba.core.runtime import nrt

    if not numba.__version__.startswith(CHECKED):
        return False
    original = caching.Cache.load_overload

    def load_overload(self, sig, target_context):  # noqa: ANN001, ANN202 - numba's signature
        nrt.rtsys.initialize(target_context)
        with self._guard_against_spurious_io_errors():
            cres = self._load_overload(sig, target_context)
            if cres is not None and (cres.objectmode or cres.lifted):
                target_context.refresh()  # object mode calls back into the registries
            return cres
        return None  # an I/O error swallowed by the guard, as numba's own

    load_overload.__wrapped__ = original  # type: ignore[attr-defined]
    caching.Cache.load_overload = load_overload
    _installed = True
    return True
