"""The backend registry: every simulator behind one table (name -> Backend).

``sim.simulate``, ``sim.select`` (model="auto"), the CLI's choices and the warn pipeline's
truth all read ``BACKENDS``. A backend answers, for one ``Scene``:

* ``simulate(scene, **options) -> Signal`` (``info["resolution"]``: a ``Resolution``,
  ``info["error"]``: an ``ErrorEstimate``);
* ``bifurcation(scene) -> Bifurcation`` of exactly the model and resolution ``simulate`` uses;
* ``equilibria(scene) -> list[EquilibriumSummary]`` and ``spectrum(scene, modes)``;
* ``resolution(scene) -> Resolution`` and ``error_estimate(scene, **options) -> ErrorEstimate``
  (relative error of mu* and of the fundamental: model error + discretisation error);
* ``cost_rank`` (0 cheapest).

Failures with valid inputs (past a fold, an unstable or absent equilibrium, a Newton that does
not converge) raise ``sim.errors.SimulationError("mu", mu, ...)`` naming mu and the backend's
own mu*.

Model errors (relative, of mu*), each re-measured by a test (tests/sim/test_backends.py):

* beam vs strip, finite end-shortening: the exact inextensible elastica's mu* exceeds the
  beam's by k dL/L with k = 0.031 (asymmetric), 0.095 (symmetric), 0.105 (antisymmetric);
* beam vs strip, extensibility: the compression strains the strip by Lambda*^2 h^2 / 12, which
  shortens the effective dL and lowers mu* by about Lambda*^2 h^2 / (24 dL) (relative);
* rod vs wide strip: plane strain raises the stretch-to-bend stiffness ratio by 1/(1 - nu^2),
  a fraction nu^2 of the extensibility term;
* normal form vs beam: computed at the scene's mu (its sigma^2 against the beam's);
* modal (linear) beam: the amplitude-frequency shift 77 (kick / omega)^2 (sim.select).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import lru_cache

from sim.errors import SimulationError
from sim.results import (
    Bifurcation,
    EquilibriumSummary,
    ErrorEstimate,
    Resolution,
    SpectrumSummary,
)
from sim.scene import Scene, Signal

#: relative mu* excess of the exact elastica over the beam, per unit dL/L
FINITE_SHORTENING = {"asymmetric": 0.031, "symmetric": 0.095, "antisymmetric": 0.105}
NONLINEAR_SHIFT_COEFF = 77.0
BEAM_TIME_ERROR = 1e-6  # nonlinear beam: substeps keep (omega dt)^2 / 12 below 1e-6


@dataclass(frozen=True)
class Backend:
    """One simulator (see the module docstring for the contract)."""

    name: str
    cost_rank: int
    simulate: Callable[..., Signal]
    bifurcation: Callable[[Scene], Bifurcation]
    equilibria: Callable[[Scene], list[EquilibriumSummary]]
    spectrum: Callable[[Scene, int], SpectrumSummary]
    resolution: Callable[[Scene], Resolution]
    error_estimate: Callable[..., ErrorEstimate]


def _past(exc: SimulationError, scene: Scene, bif: Bifurcation | None) -> SimulationError:
    """The same error, its message naming the backend's mu* (one line)."""
    msg = str(exc).splitlines()[0] if str(exc) else "no equilibrium"
    if f"mu={scene.mu!r}" not in msg:
        msg = f"no {scene.branch} equilibrium at mu={scene.mu!r} ({msg})"
    if bif is not None and f"{bif.mu_star:.6f}"[:6] not in msg:
        msg += (f"; the {bif.model} {bif.transition} of this scene is at "
                f"mu*={bif.mu_star:.8g}")  # fmt: skip
    return SimulationError("mu", scene.mu, msg)


def _guard(fn, scene: Scene, bif_of: Callable[[Scene], Bifurcation]):
    try:
        return fn()
    except SimulationError as exc:
        try:
            bif = bif_of(scene)
        except SimulationError:
            bif = None
        raise _past(exc, scene, bif) from None


def _extensibility(scene: Scene, lambda_star: float) -> float:
    return lambda_star**2 * scene.slenderness**2 / (24.0 * scene.end_shortening)


# ------------------------------------------------------------------------------ Euler beam
def _beam_bifurcation(scene: Scene) -> Bifurcation:
    from sim.euler_beam import bifurcation

    return bifurcation(scene.actuation)


def _beam_resolution(scene: Scene) -> Resolution:
    return _beam_bifurcation(scene).resolution


def _beam_model_error(scene: Scene) -> dict[str, float]:
    bif = _beam_bifurcation(scene)
    return {"finite_shortening": FINITE_SHORTENING[scene.actuation] * scene.end_shortening,
            "extensibility": _extensibility(scene, bif.lambda_star)}  # fmt: skip


def _beam_simulate(scene: Scene, *, method: str = "modal", **options) -> Signal:
    from sim.euler_beam.dynamics import impulse_response

    sig = _guard(lambda: impulse_response(scene, method=method, **options), scene,
                 _beam_bifurcation)  # fmt: skip
    info = dict(sig.info)
    info["resolution"] = _beam_resolution(scene)
    info["error"] = _beam_error(scene, method=method)
    return replace(sig, info=info)


def _beam_omega(scene: Scene) -> float:
    from sim.euler_beam import spectrum

    try:
        s2 = spectrum(scene.actuation, scene.mu, scene.branch, modes=1).sigma2[0]
    except SimulationError:
        return math.nan
    return math.sqrt(abs(s2))


def _beam_error(scene: Scene, *, method: str = "modal") -> ErrorEstimate:
    details = _beam_model_error(scene)
    if method == "modal":
        omega = _beam_omega(scene)
        details["nonlinear_shift"] = (NONLINEAR_SHIFT_COEFF * (scene.kick / omega) ** 2
                                      if omega > 0 else math.inf)  # fmt: skip
    disc = _beam_resolution(scene).mu_star_error / _beam_bifurcation(scene).mu_star
    if method == "nonlinear":
        disc += BEAM_TIME_ERROR
    return ErrorEstimate(sum(details.values()), disc, details)


def _beam_equilibria(scene: Scene) -> list[EquilibriumSummary]:
    from sim.euler_beam import equilibria, is_stable

    res = _beam_resolution(scene)
    return [EquilibriumSummary("euler-beam", scene.actuation, scene.mu, e.branch, e.lam,
                               e.w_half, e.w_quarter, is_stable(e), e.energy, res)
            for e in equilibria(scene.actuation, scene.mu)]  # fmt: skip


def _beam_spectrum(scene: Scene, modes: int = 10) -> SpectrumSummary:
    from sim.euler_beam import spectrum

    sp = _guard(lambda: spectrum(scene.actuation, scene.mu, scene.branch, modes=modes), scene,
                _beam_bifurcation)  # fmt: skip
    return SpectrumSummary("euler-beam", scene.actuation, scene.mu, scene.branch, sp.sigma2,
                           sp.equilibrium.lam, _beam_resolution(scene))  # fmt: skip


# ------------------------------------------------------------------------------ normal form
def _nf_simulate(scene: Scene, **options) -> Signal:
    from sim.normal_form import impulse_response

    sig = _guard(lambda: impulse_response(scene, **options), scene, _beam_bifurcation)
    info = dict(sig.info)
    info["resolution"] = _nf_resolution(scene)
    info["error"] = _nf_error(scene)
    return replace(sig, info=info)


def _nf_resolution(scene: Scene) -> Resolution:
    r = _beam_resolution(scene)
    return Resolution("normal-form", 1, None, r.mu_star_error, "mu* of the beam: " + r.method)


def _nf_bifurcation(scene: Scene) -> Bifurcation:
    return replace(_beam_bifurcation(scene), model="normal-form",
                   resolution=_nf_resolution(scene))  # fmt: skip


def _nf_sigma2(scene: Scene) -> float:
    from sim.normal_form import normal_form

    nf = normal_form(scene.actuation)
    return nf.sigma2(scene.mu - nf.mu_star, scene.branch)


def _nf_error(scene: Scene) -> ErrorEstimate:
    from sim.euler_beam import spectrum

    details = _beam_model_error(scene)
    try:
        s2_beam = spectrum(scene.actuation, scene.mu, scene.branch, modes=1).sigma2[0]
        details["truncation"] = abs(_nf_sigma2(scene) / s2_beam - 1.0)
    except (SimulationError, ZeroDivisionError):
        details["truncation"] = math.inf
    disc = _nf_resolution(scene).mu_star_error / _beam_bifurcation(scene).mu_star
    return ErrorEstimate(sum(details.values()), disc, details)


def _nf_equilibria(scene: Scene) -> list[EquilibriumSummary]:
    from sim.normal_form import normal_form

    nf = normal_form(scene.actuation)
    dmu = scene.mu - nf.mu_star
    out = []
    for branch, A in sorted(nf.equilibria(dmu).items()):
        s2 = nf.sigma2(dmu, branch)
        w_half = float(nf.phi([0.5])[0] * A)
        w_quarter = float(nf.phi([0.25])[0] * A)
        out.append(EquilibriumSummary("normal-form", scene.actuation, scene.mu, branch,
                                      nf.lambda_star, w_half, w_quarter, s2 < 0))  # fmt: skip
    return out


def _nf_spectrum(scene: Scene, modes: int = 1) -> SpectrumSummary:
    import numpy as np

    s2 = _guard(lambda: _nf_sigma2(scene), scene, _beam_bifurcation)
    return SpectrumSummary("normal-form", scene.actuation, scene.mu, scene.branch,
                           np.array([s2]), None, _nf_resolution(scene))  # fmt: skip


# ------------------------------------------------------------------------------ Cosserat rod
def _rod_resolution(scene: Scene) -> Resolution:
    from sim.resolution import rod_resolution

    return rod_resolution(scene.actuation, end_shortening=scene.end_shortening,
                          slenderness=scene.slenderness, poisson=scene.poisson,
                          rtol=scene.rtol, elements=scene.elements)  # fmt: skip


@lru_cache(maxsize=64)
def _rod_bifurcation_cached(actuation: str, end_shortening: float, slenderness: float,
                            poisson: float, elements: int, rtol: float | None) -> Bifurcation:
    from sim.cosserat import bifurcation

    return bifurcation(actuation, end_shortening=end_shortening, slenderness=slenderness,
                       poisson=poisson, elements=elements, rtol=rtol)  # fmt: skip


def _rod_bifurcation(scene: Scene) -> Bifurcation:
    res = _rod_resolution(scene)
    b = _rod_bifurcation_cached(scene.actuation, scene.end_shortening, scene.slenderness,
                                scene.poisson, res.size, res.rtol)  # fmt: skip
    return replace(b, resolution=res)


def _rod_simulate(scene: Scene, **options) -> Signal:
    from sim.cosserat.dynamics import simulate

    sig = _guard(lambda: simulate(scene, **options), scene, _rod_bifurcation)
    info = dict(sig.info)
    info["error"] = _rod_error(scene, time_error=info.get("time_error"))
    return replace(sig, info=info)


def _rod_error(scene: Scene, *, time_error: float | None = None) -> ErrorEstimate:
    from sim.cosserat.dynamics import steps_for
    from sim.resolution import rod_error_constant

    res = _rod_resolution(scene)
    _, mu_inf, _, _ = rod_error_constant(scene.actuation, scene.end_shortening, scene.slenderness,
                                      scene.poisson, "node")  # fmt: skip
    lam = _beam_bifurcation(scene).lambda_star
    details = {"plane_strain": scene.poisson**2 * _extensibility(scene, lam)}
    if time_error is None:
        time_error = (2.0 * math.pi / steps_for(scene.rtol)) ** 2 / 12.0
    disc = res.mu_star_error / abs(mu_inf) + time_error
    details["time_stepping"] = time_error
    return ErrorEstimate(details["plane_strain"], disc, details)


def _rod_equilibria(scene: Scene) -> list[EquilibriumSummary]:
    from sim.cosserat.api import equilibria

    out = []
    for branch in ("U_A", "U_B"):
        try:
            e = equilibria(scene.actuation, scene.mu, end_shortening=scene.end_shortening,
                           slenderness=scene.slenderness, poisson=scene.poisson,
                           elements=scene.elements, rtol=scene.rtol, branch=branch)
        except SimulationError:
            continue  # absent past its fold: not listed (as the beam's equilibria)
        n = e.w.size - 1
        out.append(EquilibriumSummary("cosserat", scene.actuation, scene.mu, branch, e.lambda_,
                                      float(e.w[n // 2]), float(e.w[n // 4]), e.stable, None,
                                      e.info.get("resolution")))  # fmt: skip
    return out


def _rod_spectrum(scene: Scene, modes: int = 10) -> SpectrumSummary:
    from sim.cosserat.api import spectrum

    def run():
        return spectrum(scene.actuation, scene.mu, end_shortening=scene.end_shortening,
                        slenderness=scene.slenderness, poisson=scene.poisson,
                        elements=scene.elements, rtol=scene.rtol, branch=scene.branch,
                        modes=modes)  # fmt: skip

    sp = _guard(run, scene, _rod_bifurcation)
    return SpectrumSummary("cosserat", scene.actuation, scene.mu, scene.branch, sp.sigma2,
                           None, sp.resolution)  # fmt: skip


BACKENDS: dict[str, Backend] = {
    "normal-form": Backend("normal-form", 0, _nf_simulate, _nf_bifurcation, _nf_equilibria,
                           _nf_spectrum, _nf_resolution, lambda s, **_: _nf_error(s)),
    "euler-beam": Backend("euler-beam", 1, _beam_simulate, _beam_bifurcation, _beam_equilibria,
                          _beam_spectrum, _beam_resolution, _beam_error),
    "cosserat": Backend("cosserat", 3, _rod_simulate, _rod_bifurcation, _rod_equilibria,
                        _rod_spectrum, _rod_resolution, lambda s, **_: _rod_error(s)),
}


def preload() -> None:
    """Import every backend's package now, in the calling thread.

    The backends import their packages lazily, inside the functions that need them. A server
    runs those functions in worker threads; two threads importing one package and one of its
    submodules at once (``sim.cosserat`` in one, ``sim.cosserat.dynamics`` in the other) take
    Python's module locks in opposite orders, and the import system breaks the deadlock by
    handing one of them a partially initialised module: an ImportError, an HTTP 500 (found by
    the fuzz on a fresh server: POST /v1/snaps and /v1/simulations). A server calls this once
    before it serves."""
    import sim.cosserat  # noqa: F401
    import sim.euler_beam  # noqa: F401
    import sim.normal_form  # noqa: F401
