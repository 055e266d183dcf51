"""Wire models of the simulator's results (``snapwarn bifurcation/equilibria/spectrum/
normal-form/simulate --json``, the resolution and accuracy every backend reports).

The simulator (``sim``) returns frozen dataclasses (``sim.results``, ``sim.select.Choice``,
``sim.normal_form.NormalForm``); ``service.convert`` turns them into these models and nothing
else builds them. Units are the paper's non-dimensional ones: the control ``mu = alpha
sqrt(L / dL)``, ``Lambda = sqrt(F L^2 / B)``, shapes W in units of ``sqrt(L dL)``, time T in
units of ``sqrt(rho b h L^4 / B)`` (so ``sigma2`` in 1/T^2 and ``omega`` in rad/T).

Strict JSON: a number that is missing or not finite is ``null``.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field

Num = float | None
"""A float on the wire: ``null`` when missing or not finite."""


class _Result(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True, validate_by_name=True,
                              validate_by_alias=True, serialize_by_alias=True)  # fmt: skip


class Resolution(_Result):
    """The discretisation a result was computed with, and its estimated error of mu*."""

    model: str = Field(description="Backend: 'normal-form', 'euler-beam' or 'cosserat'.")
    size: int = Field(description="Elements of the Cosserat rod, Galerkin functions of the "
                      "beam, 1 for the normal form.")
    rtol: Num = Field(description="Relative accuracy it was chosen from (null: the size was "
                      "given explicitly).")
    mu_star_error: Num = Field(description="Estimated discretisation error of mu* at this "
                               "size (absolute, units of mu; > 0).")
    method: str = Field(description="How mu_star_error was obtained (e.g. Richardson from "
                        "two sizes).")


class BifurcationPoint(_Result):
    """One bifurcation of the U_A branch: where it is and of which kind."""

    mu_star: Num = Field(description="Control at the bifurcation (units of mu).")
    lambda_star: Num = Field(description="Lambda of the compression there (null in tension).")
    transition: str = Field(description="'saddle-node', 'subcritical-pitchfork' or "
                            "'supercritical-pitchfork'.")
    branches: list[str] = Field(description="Branches that meet there (U_A, U_B, S_A, ...).")


class Bifurcation(BifurcationPoint):
    """The shape transition of U_A for one actuation (``snapwarn bifurcation --json``)."""

    actuation: str = Field(description="'asymmetric', 'symmetric' or 'antisymmetric'.")
    model: str = Field(description="Backend that computed it.")
    secondary: list[BifurcationPoint] = Field(
        default_factory=list, description="Later bifurcations of U_A (symmetric: the fold "
        "U_A / W_B).")
    mu_star_error: Num = Field(default=None, description="Estimated discretisation error of "
                               "mu* (absolute, units of mu; null when unknown).")
    resolution: Resolution | None = None
    elements: int | None = Field(default=None, description="Elements of the Cosserat rod "
                                 "(null for the other backends).")
    end_shortening: Num = Field(default=None, description="dL/L of the strip (Cosserat rod "
                                "only; the beam is the dL/L -> 0 limit).")
    slenderness: Num = Field(default=None, description="Thickness h/L of the strip (Cosserat "
                             "rod only).")


class Equilibrium(_Result):
    """One equilibrium at mu, as every backend reports it."""

    branch: str = Field(description="Branch name (U_A, U_B, S_A, S_B, W_A, W_B).")
    lambda_: Num = Field(alias="lambda", description="Lambda = sqrt(F L^2 / B) (negative: "
                         "tension).")
    w_half: Num = Field(description="W(1/2), units of sqrt(L dL).")
    w_quarter: Num = Field(description="W(1/4), units of sqrt(L dL).")
    energy: Num = Field(default=None, description="Bending energy, units of B dL / L^2 "
                        "(beam only; null otherwise).")
    stable: bool = Field(description="Linearly stable (every sigma^2 < 0).")


class Equilibria(_Result):
    """Every equilibrium of one scene at mu (``snapwarn equilibria --json``)."""

    actuation: str
    mu: Num = Field(description="Control (units of mu).")
    model: str = Field(description="Backend asked for.")
    equilibria: list[Equilibrium]
    resolution: Resolution | None = None


class Spectrum(_Result):
    """Linear spectrum of one equilibrium, ordered by |sigma^2| (``snapwarn spectrum
    --json``)."""

    actuation: str
    model: str
    mu: Num = Field(description="Control (units of mu).")
    branch: str
    lambda_: Num = Field(default=None, alias="lambda", description="Lambda of the equilibrium "
                         "(null when the backend does not report it).")
    sigma2: list[Num] = Field(description="Eigenvalues sigma^2, 1/T^2 (< 0: a stable "
                              "oscillation).")
    omega: list[Num] = Field(description="sqrt(|sigma^2|), rad/T.")
    sigma2_error: Num = Field(default=None, description="Estimated relative error of the "
                              "fundamental's sigma^2 (Richardson, Cosserat rod only).")
    resolution: Resolution | None = None


class ErrorEstimate(_Result):
    """Estimated relative error of mu* and of the fundamental's sigma^2 a backend makes on a
    scene: its physics against the strip plus its discretisation (never 0)."""

    model: Num = Field(description="Relative error of the model's physics.")
    discretisation: Num = Field(description="Relative error of the discretisation.")
    total: Num = Field(description="model + discretisation.")
    details: dict[str, Num] = Field(default_factory=dict, description="Each term by name "
                                    "(e.g. 'extensibility', 'truncation').")


class BackendChoice(_Result):
    """The backend ``model="auto"`` picked for a scene, and why."""

    model: str = Field(description="'normal-form', 'euler-beam' or 'cosserat'.")
    method: str | None = Field(description="'modal' or 'nonlinear' for the beam.")
    reason: str = Field(description="One sentence with the numbers that decided.")
    error: ErrorEstimate = Field(description="The chosen backend's estimated relative error.")
    estimates: dict[str, Num] = Field(default_factory=dict, description="Estimated total "
                                      "relative error of each candidate evaluated.")
    rtol: Num = Field(description="The relative accuracy requested.")
    met: bool = Field(description="False when no candidate meets rtol (the most accurate one "
                      "was chosen).")


class NormalForm(_Result):
    """Coefficients of the amplitude equation at mu* (``snapwarn normal-form --json``)."""

    actuation: str
    transition: str
    mu_star: Num = Field(description="Control at the transition (units of mu).")
    lambda_star: Num = Field(description="Lambda at mu*.")
    coefficients: dict[str, Num] = Field(description="{a1, a2} (saddle-node) or {b1, b2} "
                                         "(pitchfork) of the amplitude equation, in units of "
                                         "the amplitude A (units of sqrt(L dL)) and of T.")
    I1: Num = Field(description="Integral of Phi0^2 over X in [0, 1] (critical mode Phi0).")
    I2: Num = Field(description="Integral of Phi0'^2 over X in [0, 1].")


class SimulationInfo(_Result):
    """What the backend that ran a simulation reports about it (``sim.scene.Signal.info``; a
    simulated signal's ``metadata.info``): every backend's resolution, error estimate and
    spectrum, the choice of ``model="auto"``, and each backend's own numbers (null where the
    backend that ran does not report them)."""

    resolution: Resolution | None = Field(default=None, description="Discretisation used and "
                                          "its estimated mu* error (every backend).")
    error: ErrorEstimate | None = Field(default=None, description="Estimated relative error "
                                        "of mu* and of the fundamental's sigma^2 (every "
                                        "backend).")
    auto: BackendChoice | None = Field(default=None, description="With model='auto': the "
                                       "backend picked and why (null otherwise).")
    sigma2: list[Num] = Field(default_factory=list, description="Lowest eigenvalues sigma^2 "
                              "of the equilibrium, 1/T^2, fundamental first (the normal "
                              "form: its one).")
    lambda_: Num = Field(default=None, alias="lambda", description="Lambda of the equilibrium "
                         "(Euler beam, Cosserat rod).")
    # the normal form
    dmu: Num = Field(default=None, description="mu - mu*, units of mu (normal form).")
    coefficients: dict[str, Num] | None = Field(
        default=None, description="{a1, a2} (saddle-node) or {b1, b2} (pitchfork) of the "
        "amplitude equation (normal form; see NormalForm).")
    # the Euler beam
    method: str | None = Field(default=None, description="'modal' or 'nonlinear' (Euler "
                               "beam).")
    galerkin_n: int | None = Field(default=None, description="Galerkin basis size (Euler "
                                   "beam).")
    modes: int | None = Field(default=None, description="Modes superposed (Euler beam, "
                              "modal).")
    substeps: int | None = Field(default=None, description="Integration steps per sample "
                                 "(Euler beam, nonlinear).")
    completed: bool | None = Field(default=None, description="Whether the nonlinear "
                                   "integration reached the last sample (false after a "
                                   "Newton failure; Euler beam, nonlinear).")
    # the Cosserat rod
    omega: Num = Field(default=None, description="sqrt(|sigma^2|) of the fundamental, rad/T "
                       "(Cosserat rod).")
    min_eigenvalue: Num = Field(default=None, description="Smallest eigenvalue of the rod's "
                                "energy Hessian at the equilibrium (> 0: stable; Cosserat "
                                "rod).")
    sigma2_error: Num = Field(default=None, description="Estimated relative error of the "
                              "fundamental's sigma^2 (Richardson, n against n/2; Cosserat "
                              "rod).")
    time_error: Num = Field(default=None, description="Estimated relative error of the time "
                            "stepping, (2 pi / steps per period)^2 / 12 (Cosserat rod).")
    internal_dt: Num = Field(default=None, description="Integration step, T (Cosserat rod).")
    steps: int | None = Field(default=None, description="Integration steps taken (Cosserat "
                              "rod).")
    newton_iterations: int | None = Field(default=None, description="Newton iterations, all "
                                          "steps together (Cosserat rod).")
    cpu_s: Num = Field(default=None, description="CPU time of the integration, s (Cosserat "
                       "rod).")
    stop: str | None = Field(default=None, description="Why the integration stopped ('done' "
                             "when it reached the last sample; Cosserat rod).")
    clamp: str | None = Field(default=None, description="'node' or 'element' (Cosserat rod).")
    rho_inf: Num = Field(default=None, description="Generalised-alpha spectral radius at "
                         "infinite frequency (Cosserat rod).")
    elements: int | None = Field(default=None, description="Elements of the rod (Cosserat "
                                 "rod).")


class SimulationMetadata(_Result):
    """A simulated signal's ``metadata`` (``POST /v1/simulations``): the scene, the backend
    that ran it and what that backend reports."""

    scene: dict[str, Any] = Field(description="The scene simulated: the request's fields but "
                                  "model, background and name (see SimulationRequest).")
    model: str = Field(description="Backend that ran (the one picked for model='auto').")
    w_static: Num = Field(description="W(probe) at equilibrium, units of sqrt(L dL).")
    info: SimulationInfo


class Simulation(_Result):
    """A simulated impulse response written to a CSV file (``snapwarn simulate --json``)."""

    path: str = Field(description="The CSV file written (header t,w).")
    samples: int
    model: str = Field(description="Backend that ran (the one picked for model='auto').")
    actuation: str
    mu: Num = Field(description="Control (units of mu).")
    branch: str
    dt: Num = Field(description="Sample step, T.")
    duration: Num = Field(description="Time of the last sample, T.")
    w_static: Num = Field(description="W(probe) at equilibrium, units of sqrt(L dL).")
    sigma2: Num = Field(description="Fundamental's sigma^2 of the equilibrium, 1/T^2.")
    resolution: Resolution | None = None
    error: ErrorEstimate | None = Field(default=None, description="Estimated relative error.")
    auto: BackendChoice | None = Field(default=None, description="With model='auto': the "
                                       "backend picked and why (null otherwise).")


class SpectrumPoint(_Result):
    """The lowest eigenvalues of U_A at one mu (the demo's slowing-down table)."""

    actuation: str
    mu: Num = Field(description="Control (units of mu).")
    sigma2: list[Num] = Field(description="Eigenvalues sigma^2, 1/T^2, by |sigma^2|.")


class ImpulseResponseSummary(_Result):
    """One simulated impulse response, summarised (the demo's example record)."""

    actuation: str
    mu: Num = Field(description="Control (units of mu).")
    samples: int
    dt: Num = Field(description="Sample step, T.")
    w_static: Num = Field(description="W(probe) at equilibrium, units of sqrt(L dL).")
    w_min: Num = Field(description="Smallest W(probe, t) recorded, units of sqrt(L dL).")
    w_max: Num = Field(description="Largest W(probe, t) recorded, units of sqrt(L dL).")
    sigma2: Num = Field(description="Fundamental's sigma^2 of the equilibrium, 1/T^2.")


class BeamSummary(_Result):
    """The Euler beam in brief (``snapwarn demo``): its three transitions, the slowing down of
    U_A's fundamental as mu -> mu*, and one impulse response."""

    transitions: list[Bifurcation]
    spectrum_U_A: list[SpectrumPoint]
    impulse_response: ImpulseResponseSummary
