"""``model="auto"``: the cheapest backend whose estimated total error meets the requested
accuracy, and why.

Candidates by cost (``sim.backends.BACKENDS[...].cost_rank``): the normal form (one degree of
freedom), the Euler beam by modal superposition (linear), the Euler beam by nonlinear
integration, the discrete Cosserat rod. Each one's estimated relative error of mu* (and of the
fundamental) is its model error plus its discretisation error (``Backend.error_estimate``);
none is ever 0. The requested accuracy is the scene's ``rtol``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from sim.backends import NONLINEAR_SHIFT_COEFF
from sim.errors import ParameterError
from sim.results import ErrorEstimate
from sim.scene import Scene

__all__ = ["LADDER", "NONLINEAR_SHIFT_COEFF", "Choice", "choose_model", "estimate_errors"]
LADDER = (("normal-form", "normal-form", None), ("euler-beam", "euler-beam", "modal"),
          ("euler-beam-nonlinear", "euler-beam", "nonlinear"), ("cosserat", "cosserat", None))


@dataclass(frozen=True)
class Choice:
    """The backend picked for a scene.

    Attributes
    ----------
    model : str
        "normal-form", "euler-beam" or "cosserat".
    method : str or None
        "modal" or "nonlinear" for the beam.
    reason : str
        One sentence with the numbers that decided.
    estimate : ErrorEstimate
        The chosen backend's estimated relative error (model + discretisation).
    estimates : dict
        Estimated total relative error of each candidate evaluated (name -> float).
    rtol : float
        The accuracy requested.
    met : bool
        False when no candidate meets ``rtol`` (the most accurate one is chosen).
    """

    model: str
    method: str | None
    reason: str
    estimate: ErrorEstimate
    estimates: dict = field(default_factory=dict)
    rtol: float = 0.0
    met: bool = True


def estimate_errors(scene: Scene) -> dict[str, ErrorEstimate]:
    """Every candidate's estimated relative error on this scene (keys of ``LADDER``)."""
    from sim.backends import BACKENDS

    out = {}
    for key, model, method in LADDER:
        opts = {"method": method} if method else {}
        out[key] = BACKENDS[model].error_estimate(scene, **opts)
    return out


def choose_model(scene: Scene, *, accuracy: float | None = None) -> Choice:
    """The cheapest backend whose estimated total relative error is <= the accuracy.

    Parameters
    ----------
    scene : Scene
    accuracy : float, optional
        Requested relative accuracy of mu* and of the fundamental, in (0, 0.1); default
        ``scene.rtol``.
    """
    from sim.backends import BACKENDS

    rtol = scene.rtol if accuracy is None else accuracy
    if not (isinstance(rtol, (int, float)) and 0 < rtol < 0.1):
        raise ParameterError("rtol", rtol, f"rtol (accuracy) must be in (0, 0.1), got {rtol!r}")
    if accuracy is not None:
        scene = scene.with_(rtol=float(accuracy))
    est: dict[str, ErrorEstimate] = {}
    ladder = sorted(LADDER, key=lambda c: (BACKENDS[c[1]].cost_rank, c[0]))
    for key, model, method in ladder:
        opts = {"method": method} if method else {}
        e = BACKENDS[model].error_estimate(scene, **opts)
        est[key] = e
        if e.total <= rtol:
            skipped = [f"{k} ({v.total:.1e})" for k, v in est.items() if k != key]
            why = (f"{key}: estimated relative error {e.total:.1e} (model {e.model:.1e} + "
                   f"discretisation {e.discretisation:.1e}) <= rtol {rtol:g}")
            if skipped:
                why += f"; cheaper but not accurate enough: {', '.join(skipped)}"
            return Choice(model, method, why, e, {k: v.total for k, v in est.items()}, rtol)
    key = min(est, key=lambda k: est[k].total if math.isfinite(est[k].total) else math.inf)
    _, model, method = next(c for c in LADDER if c[0] == key)
    e = est[key]
    why = (f"no backend meets rtol {rtol:g}; the most accurate is {key} with an estimated "
           f"relative error {e.total:.1e} ("
           + ", ".join(f"{k} {v:.1e}" for k, v in e.details.items()) + ")")
    return Choice(model, method, why, e, {k: v.total for k, v in est.items()}, rtol, False)
