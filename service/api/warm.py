"""Start-up of the analysis workers: import the numerics once, report what imported.

The routes import the numerics plainly; this module only warms a worker process (so that the
first request does not pay the imports and the JIT cache load) and tells ``/healthz`` which
parts of the numerics import in this installation.
"""

from __future__ import annotations

import gc
import importlib

#: What ``/healthz`` reports under ``numerics``: name -> module.
MODULES: dict[str, str] = {
    "simulate": "sim",
    "detect": "service.analysis.detect",
    "classify": "service.analysis.classify",
    "predict": "service.analysis.predict",
    "warn": "service.analysis.pipeline",
    "sweep_from_signals": "service.analysis.pipeline",
}


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
    """Import what a worker will need (called once per worker at start-up)."""
    import matplotlib

    matplotlib.use("Agg")
    out = available()
    # What start-up made lives as long as the worker: out of the collector's way (its passes
    # then walk what a call allocates, not the numerics' modules).
    gc.freeze()
    return out
