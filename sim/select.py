"""``model="auto"``: the cheapest backend accurate enough for a scene, and why.

Backends by cost: the normal form (one degree of freedom), the Euler beam by modal
superposition (linear, a few modes), the Euler beam by nonlinear integration, the discrete
Cosserat rod. Each has a model error that the scene decides:

* Euler beam vs a strip of finite end-shortening: the beam is the dL/L -> 0 limit. The paper's
  Table 1 (rod at dL/L = 1e-2 against the beam) gives relative mu* differences of 1.1 %, 1.4 %,
  1.7 %: we take 1.7 dL/L as the beam's relative error.
* Normal form vs beam: computed, not guessed: its sigma^2 against the beam spectrum at the
  scene's mu (one Galerkin solve, about a millisecond).
* Linear vs nonlinear: the fundamental's frequency shifts with the response amplitude
  A ~ kick / omega; the beam's nonlinear integration gives a relative shift of about
  77 (kick / omega)^2 (measured: tests/sim/test_select.py re-measures it). Above the requested
  accuracy, a linear (modal) response is not accurate enough.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from sim.scene import Scene

BEAM_ERROR_PER_END_SHORTENING = 1.7
NONLINEAR_SHIFT_COEFF = 77.0
COST_RANK = ("normal-form", "euler-beam", "euler-beam-nonlinear", "cosserat")


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
    estimates : dict
        Estimated relative error of each candidate.
    """

    model: str
    method: str | None
    reason: str
    estimates: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"model": self.model, "method": self.method, "reason": self.reason,
                "estimates": dict(self.estimates)}  # fmt: skip


def estimate_errors(scene: Scene) -> dict[str, float]:
    """Relative error of sigma^2 (and mu*) each backend would make on this scene."""
    from sim.euler_beam import BeamError, bifurcation, spectrum
    from sim.normal_form import normal_form

    beam_model = BEAM_ERROR_PER_END_SHORTENING * scene.end_shortening
    est: dict[str, float] = {}
    try:
        s2_beam = spectrum(scene.actuation, scene.mu, scene.branch, modes=1).sigma2[0]
    except BeamError:
        s2_beam = math.nan  # no beam equilibrium on this branch here (past mu*)
    omega = math.sqrt(abs(s2_beam)) if math.isfinite(s2_beam) else math.nan
    shift = NONLINEAR_SHIFT_COEFF * (scene.kick / omega) ** 2 if omega > 0 else math.inf
    est["nonlinear_shift"] = shift
    # normal form
    nf = normal_form(scene.actuation)
    dmu = scene.mu - bifurcation(scene.actuation).mu_star
    try:
        s2_nf = nf.sigma2(dmu, scene.branch)
        nf_err = abs(s2_nf / s2_beam - 1.0) if math.isfinite(s2_beam) else math.inf
    except (ValueError, ZeroDivisionError):
        nf_err = math.inf
    est["normal-form"] = nf_err + beam_model
    est["euler-beam"] = beam_model + shift
    est["euler-beam-nonlinear"] = beam_model if math.isfinite(s2_beam) else math.inf
    est["cosserat"] = 0.0  # the reference fidelity of the ladder
    return est


def choose_model(scene: Scene, *, accuracy: float = 1e-2) -> Choice:
    """The cheapest backend whose estimated relative error is below ``accuracy``.

    Parameters
    ----------
    scene : Scene
    accuracy : float
        Requested relative accuracy of the fundamental's sigma^2 (and of mu*), in (0, 1).
    """
    if not (isinstance(accuracy, (int, float)) and 0 < accuracy < 1):
        raise ValueError(f"accuracy must be in (0, 1), got accuracy={accuracy!r}")
    est = estimate_errors(scene)
    for name in COST_RANK:
        err = est[name]
        if err <= accuracy:
            model, method = {
                "normal-form": ("normal-form", None),
                "euler-beam": ("euler-beam", "modal"),
                "euler-beam-nonlinear": ("euler-beam", "nonlinear"),
                "cosserat": ("cosserat", None),
            }[name]
            skipped = [f"{n} ({est[n]:.1e})" for n in COST_RANK[: COST_RANK.index(name)]]
            why = f"{name}: estimated relative error {err:.1e} <= {accuracy:g}"
            if skipped:
                why += f"; cheaper but not accurate enough: {', '.join(skipped)}"
            return Choice(model, method, why, est)
    raise AssertionError("unreachable: the Cosserat rod is always a candidate")
