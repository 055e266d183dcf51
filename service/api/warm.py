"""Start-up of the analysis workers: load (or compile) the kernels, report what imported.

The routes import the numerics plainly; this module warms a worker process before it serves:
imports, then :func:`service.warmup.warm` over the analysis paths (detect, predict, classify,
a lab sweep, a live update), so that numba loads their kernels from its cache -- or compiles
what the cache lacks, here and not inside a request's time limit. Until every worker is warm
the app is not *ready* (``/healthz`` says so; analysis requests wait a little, then get 503
with ``Retry-After``: see :class:`service.api.state.AppState`). It also tells ``/healthz``
which parts of the numerics import in this installation.
"""

from __future__ import annotations

import gc
import importlib
import logging

log = logging.getLogger("snapwarn.api")

#: What ``/healthz`` reports under ``numerics``: name -> module.
MODULES: dict[str, str] = {
    "simulate": "sim",
    "detect": "service.analysis.detect",
    "classify": "service.analysis.classify",
    "predict": "service.analysis.predict",
    "warn": "service.analysis.pipeline",
    "sweep_from_signals": "service.analysis.pipeline",
}

_WARMED: dict[str, bool] | None = None  # this process's answer, once warm


def available() -> dict[str, bool]:
    """Which numerics modules import (a broken one is reported, never raised)."""
    out = {}
    for name, module in MODULES.items():
        try:
            importlib.import_module(module)
            out[name] = True
        except Exception:  # noqa: BLE001 - health reports, it does not fail
            out[name] = False
    return out


def warm() -> dict[str, bool]:
    """Import what a worker will need and load its kernels (once per worker process)."""
    global _WARMED
    if _WARMED is not None:
        return dict(_WARMED)
    import matplotlib

    matplotlib.use("Agg")
    out = available()
    try:
        from service.warmup import warm as warm_kernels

        rep = warm_kernels(models=(), analysis=True)
        if rep.compiled:
            log.info("analysis worker compiled %d kernels missing from numba's cache (%.1f s)",
                     len(rep.compiled), rep.seconds)  # fmt: skip
        for f in rep.failed:
            log.warning("kernel warm-up: %s", f)
    except Exception:  # noqa: BLE001 - warming is an optimisation: the requests still run
        log.exception("kernel warm-up failed")
    # What start-up made lives as long as the worker: out of the collector's way (its passes
    # then walk what a call allocates, not the numerics' modules).
    gc.freeze()
    _WARMED = out
    return dict(out)
