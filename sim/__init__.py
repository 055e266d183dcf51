"""snapwarn simulators: normal forms, Euler beam, discrete Cosserat rod (pure numerics).

``simulate(scene, model=...)`` is the one entry point: it returns a ``Signal`` whatever the
backend, so the detector and the warn pipeline run unchanged on any of them. The backends are
registered in ``sim.backends.BACKENDS``; ``MODELS`` and ``ACTUATIONS`` are the vocabulary.
"""

from __future__ import annotations

from sim.errors import ParameterError, SimulationError
from sim.results import Bifurcation, BifurcationPoint, Resolution
from sim.scene import ACTUATIONS, BRANCHES, MODELS, Scene, SceneError, Signal

__all__ = ["ACTUATIONS", "BRANCHES", "MODELS", "Bifurcation", "BifurcationPoint",
           "ParameterError", "Resolution", "Scene", "SceneError", "Signal", "SimulationError",
           "simulate"]  # fmt: skip


def simulate(scene: Scene, model: str = "euler-beam", **options) -> Signal:
    """Simulate an impulse response with the chosen backend.

    Parameters
    ----------
    scene : Scene
    model : {"normal-form", "euler-beam", "cosserat", "auto"}
        "auto" picks the cheapest backend whose estimated error meets ``scene.rtol``
        (``sim.select``); ``info["auto"]`` (a ``sim.select.Choice``) names it, its estimate
        and the reason.
    **options
        Backend options (e.g. ``method="nonlinear"`` for the Euler beam).

    Returns
    -------
    Signal
        ``info["resolution"]`` (a ``Resolution``: discretisation used, its mu* error) and
        ``info["error"]`` (an ``ErrorEstimate``: relative error, model + discretisation);
        ``service.convert`` gives their wire documents.
    """
    from sim.backends import BACKENDS

    if model not in MODELS:
        raise SceneError("model", model, f"model must be one of {MODELS}, got {model!r}")
    if model == "auto":
        from sim.select import choose_model

        choice = choose_model(scene)
        extra = {"method": choice.method} if choice.model == "euler-beam" else {}
        sig = BACKENDS[choice.model].simulate(scene, **extra)
        info = dict(sig.info)
        info["auto"] = choice
        return Signal(sig.t, sig.w, sig.w_static, sig.model, sig.scene, info)
    return BACKENDS[model].simulate(scene, **options)
