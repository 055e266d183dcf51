"""snapwarn simulators: normal forms, Euler beam, discrete Cosserat rod (pure numerics).

``simulate(scene, model=...)`` is the one entry point: it returns a ``Signal`` whatever the
backend, so the detector and the warn pipeline run unchanged on any of them.
"""

from __future__ import annotations

from sim.scene import ACTUATIONS, BRANCHES, MODELS, Scene, SceneError, Signal

__all__ = ["ACTUATIONS", "BRANCHES", "MODELS", "Scene", "SceneError", "Signal", "simulate"]


def simulate(scene: Scene, model: str = "euler-beam", **options) -> Signal:
    """Simulate an impulse response with the chosen backend.

    Parameters
    ----------
    scene : Scene
    model : {"normal-form", "euler-beam", "cosserat", "auto"}
        "auto" picks the cheapest backend accurate enough for the scene (``sim.select``).
    **options
        Backend options (e.g. ``method="nonlinear"`` for the Euler beam; ``accuracy`` for
        "auto").
    """
    if model not in MODELS:
        raise SceneError(f"model must be one of {MODELS}, got {model!r}")
    if model == "auto":
        from sim.select import choose_model

        choice = choose_model(scene, **options)
        extra = {"method": choice.method} if choice.model == "euler-beam" else {}
        sig = simulate(scene, choice.model, **extra)
        info = dict(sig.info)
        info["auto"] = choice.to_dict()
        return Signal(sig.t, sig.w, sig.w_static, sig.model, sig.scene, info)
    if model == "euler-beam":
        from sim.euler_beam.dynamics import impulse_response

        return impulse_response(scene, **options)
    if model == "normal-form":
        from sim.normal_form import impulse_response as nf_response

        return nf_response(scene, **options)
    from sim import cosserat

    return cosserat.simulate(scene, **options)
