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

numba is imported (:func:`import_numba`; ``njit`` here is numba's, imported so) without
the two imports numba's ``__init__`` makes for features no kernel here uses: ``scipy`` (only to
check its version; numba's linear algebra imports scipy's LAPACK itself when it compiles) and
``yaml`` (only to read a ``.numba_config.yaml`` in the working directory, so it is imported
whenever that file is there). ~35 ms CPU of a command that loads no scipy otherwise (``snapwarn
detect``). Should a numba version need either at import, it is imported again the plain way.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType

#: modules numba's ``__init__`` imports for a version check and an optional config file only
OPTIONAL_AT_IMPORT = ("scipy", "yaml")
_CONFIG_FILE = ".numba_config.yaml"  # numba's own name (numba.core.config._config_fname)


def import_numba(without: tuple[str, ...] = OPTIONAL_AT_IMPORT) -> ModuleType:
    """``import numba``, keeping the modules ``without`` out of numba's own import.

    While numba's package imports, each of ``without`` not yet loaded is marked absent in
    ``sys.modules`` (``import`` raises ImportError, which numba catches for both); afterwards they
    import normally. ``yaml`` is not kept out when numba's config file is in the working
    directory, and nothing is kept out while other threads run (a server's thread pool: one of
    them could import scipy meanwhile). Should numba fail to import without them, its partly
    imported modules are dropped and it is imported the plain way. Returns the numba module.
    """
    if "numba" in sys.modules:
        return sys.modules["numba"]
    kept_out = [m for m in without if m not in sys.modules]
    threading = sys.modules.get("threading")
    if threading is not None and threading.active_count() > 1:
        kept_out = []  # another thread could import one of them meanwhile and fail
    if "yaml" in kept_out and os.path.isfile(_CONFIG_FILE):
        kept_out.remove("yaml")
    for m in kept_out:
        sys.modules[m] = None  # type: ignore[assignment]  # import raises ImportError
    try:
        import numba
    except ImportError:
        for m in [m for m in sys.modules if m == "numba" or m.startswith("numba.")]:
            del sys.modules[m]
        numba = None
    finally:
        for m in kept_out:
            if m in sys.modules and sys.modules[m] is None:
                del sys.modules[m]
    if numba is None:
        import numba
    return numba


def __getattr__(name: str):  # noqa: ANN202 - module attribute
    if name == "njit":  # numba's, imported by import_numba() at first use
        return import_numba().njit
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

@contextmanager
def quiet_llvm_lock() -> Iterator[None]:
    """numba's ``numba:llvm_lock`` events off inside (they are restored after).

    numba registers callbacks on llvmlite's lock that broadcast a start and an end event
    around every call into LLVM, for its compile timers. Loading a cached kernel makes a
    few hundred such calls (reading its bitcode, listing its symbols): some 10 ms CPU of a
    ``snapwarn detect`` for events no one listens to while nothing compiles. Only while this
    thread is the only one (the callback list is global: another thread's compilation keeps
    its events) and where llvmlite keeps the list as this was written against."""
    import threading

    from llvmlite.binding import ffi

    callbacks = getattr(getattr(getattr(ffi, "lib", None), "_lock", None), "_cblist", None)
    if not isinstance(callbacks, list) or not callbacks or threading.active_count() > 1:
        yield
        return
    saved = list(callbacks)
    callbacks.clear()
    try:
        yield
    finally:
        callbacks[:0] = saved


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
    numba = import_numba()
    from numba.core import caching
    from numba.core.runtime import nrt

    if not numba.__version__.startswith(CHECKED):
        return False
    original = caching.Cache.load_overload

    def load_overload(self, sig, target_context):  # noqa: ANN001, ANN202 - numba's signature
        with quiet_llvm_lock():
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
