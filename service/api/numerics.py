"""The one door from the web layer to the numerics (``sim``, ``service.analysis``).

Everything here is imported lazily and called inside a worker process (or thread) of the
analysis pool, never on the event loop. A numerics entry point that is not installed yet
answers 501 (an :class:`ApiProblem`); a ``ValueError`` from the numerics (their validation at
the door names the parameter and echoes the value) answers 422. No physics lives here: these
functions only convert arrays and documents.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from service.api.problems import ApiProblem
from service.api.storage import sanitize

ENTRY_POINTS: dict[str, tuple[str, str]] = {
    "simulate": ("sim", "simulate"),
    "detect": ("service.analysis.detect", "detect"),
    "classify": ("service.analysis.classify", "classify"),
    "predict": ("service.analysis.predict", "predict"),
    "warn": ("service.analysis.pipeline", "warn"),
    "sweep_from_signals": ("service.analysis.pipeline", "sweep_from_signals"),
}


def load(name: str) -> Callable[..., Any]:
    """The callable behind ``name`` (see ENTRY_POINTS), or a 501 problem if absent."""
    module, attr = ENTRY_POINTS[name]
    try:
        mod = importlib.import_module(module)
        return getattr(mod, attr)
    except ModuleNotFoundError as exc:
        if exc.name and not module.startswith(exc.name) and exc.name != module:
            raise  # a real missing dependency, not a missing entry point
        raise _unavailable(module, attr) from None
    except AttributeError:
        raise _unavailable(module, attr) from None


def _unavailable(module: str, attr: str) -> ApiProblem:
    return ApiProblem(
        501,
        f"{module}.{attr} is not available in this installation yet; this resource needs it",
        title="Numerics not available",
        slug="numerics-unavailable",
        field="numerics",
        value=f"{module}.{attr}",
    )


def available() -> dict[str, bool]:
    """Which entry points can be loaded (imports the numerics modules)."""
    out = {}
    for name in ENTRY_POINTS:
        try:
            load(name)
            out[name] = True
        except ApiProblem:
            out[name] = False
        except Exception:  # noqa: BLE001 - a broken module is "not available" for health
            out[name] = False
    return out


@contextmanager
def _calling(what: str) -> Iterator[None]:
    """Map a numerics module missing *during* a call (work in progress) to 501."""
    try:
        yield
    except ModuleNotFoundError as exc:
        name = exc.name or ""
        if name.split(".")[0] == "sim" or name.startswith("service.analysis"):
            raise ApiProblem(
                501,
                f"{what} needs {name}, which is not available in this installation yet",
                title="Numerics not available",
                slug="numerics-unavailable",
                field="numerics",
                value=name,
            ) from None
        raise


def _field_of(message: str, default: str) -> str:
    head = message.split(" ", 1)[0].strip(":,")
    return head if head.isidentifier() else default


def _as_problem(exc: ValueError, default_field: str) -> ApiProblem:
    msg = str(exc)
    return ApiProblem(422, msg, field=_field_of(msg, default_field), value=None)


def warm() -> dict[str, bool]:
    """Import what the workers will need (called once per worker at startup)."""
    import matplotlib

    matplotlib.use("Agg")
    return available()


# --- entry points (run in the pool) ----------------------------------------------------------
def detect_doc(w: np.ndarray, dt: float, method: str = "auto") -> dict[str, Any]:
    """``detect(w, dt=dt, method=method).to_dict()`` as strict JSON."""
    detect = load("detect")
    try:
        with _calling("detection"):
            res = detect(np.asarray(w, dtype=np.float64), dt=float(dt), method=method)
    except ValueError as exc:
        raise _as_problem(exc, "w") from None
    return sanitize(res.to_dict())


def check_scene(params: dict[str, Any]) -> None:
    """Validate scene parameters with ``sim.scene.Scene`` (422 naming the field)."""
    from sim.scene import Scene, SceneError

    try:
        Scene(**params)
    except SceneError as exc:
        raise _as_problem(exc, "scene") from None
    except TypeError as exc:
        raise ApiProblem(422, str(exc), field="scene", value=sorted(params)) from None


def simulate(params: dict[str, Any], model: str) -> dict[str, Any]:
    """Run ``sim.simulate(Scene(**params), model=model)``; arrays and the static level."""
    from sim.scene import Scene, SceneError

    simulate_fn = load("simulate")
    try:
        scene = Scene(**params)
        with _calling(f"simulation with model={model!r}"):
            sig = simulate_fn(scene, model=model)
    except (SceneError, ValueError) as exc:
        raise _as_problem(exc, "scene") from None
    t = np.asarray(sig.t, dtype=np.float64)
    w = np.asarray(sig.w, dtype=np.float64)
    w_static = float(sig.w_static)
    return {
        "t": t,
        "w": w,
        "w_static": w_static if math.isfinite(w_static) else None,
        "model": str(sig.model),
        "info": sanitize(dict(sig.info or {})),
    }


def warn(params: dict[str, Any], progress: Callable[[float, str], None]) -> dict[str, Any]:
    """The warn pipeline on simulated sweeps (``snapwarn warn --json`` document)."""
    fn = load("warn")
    kwargs = {k: v for k, v in params.items() if v is not None}
    try:
        with _calling("the warn pipeline"):
            res = fn(**kwargs, progress=progress)
    except ValueError as exc:
        raise _as_problem(exc, "simulate") from None
    return sanitize(res.to_dict())


def sweep_from_signals(
    items: list[tuple[np.ndarray, float, float]],
    names: list[str],
    progress: Callable[[float, str], None],
) -> dict[str, Any]:
    """The pipeline on recorded signals: ``[(w, dt, control_value), ...]`` -> document."""
    fn = load("sweep_from_signals")
    try:
        with _calling("the sweep pipeline"):
            res = fn(items, names=names, progress=progress)
    except ValueError as exc:
        raise _as_problem(exc, "measurements") from None
    return sanitize(res.to_dict())


def load_ok(name: str) -> bool:
    """True if entry point ``name`` loads; a 501 problem otherwise (for a check in the pool)."""
    load(name)
    return True
