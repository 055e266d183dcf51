"""The rules that withhold a type, as a table (:data:`RULES`): the most probable law is named only
when none of them finds that the records cannot decide it yet.

Each :class:`Rule` has a flag code, the reason in one line, the test that pins it, and a check
that returns the flag's message when the type must be withheld (``None`` otherwise). They run in
the table's order (:func:`withhold`); the ones of stage ``"classification"`` inside
:func:`.classification.classify_sweep`, the one of stage
``"prediction"`` in :func:`.prediction.predict` (where the mixture's
probabilities are known). How each threshold was measured: docs/predictor.md (the ledger).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from service.analysis.common import Flag
from service.analysis.predictor._dist import chi2_ppf
from service.analysis.predictor.compare import ModelFit, fold_rival_gap, secondary_fold
from service.analysis.predictor.likelihood import U_MAX as FOLD_U_MAX
from service.analysis.predictor.likelihood import _Comp, _profile, _sigma_comp, _w_exps
from service.analysis.predictor.sweep import Sweep

__all__ = [
    "DECISIVE",
    "FOLD_U_SEEN",
    "MIN_T_RATIO",
    "RULES",
    "STATIC_ALPHA",
    "STATIC_POINTS",
    "Evidence",
    "Rule",
    "static_consistency",
    "withhold",
]

#: T/T0 below which the type is never named (ledger: "slowdown_not_reached")
MIN_T_RATIO = 2.75
#: a conformal pitchfork law behaves as a pitchfork (|sigma^2| ~ x) only within its secondary
#: fold's distance delta of mu* (local exponent u / (2 sqrt(1+u) (sqrt(1+u) - 1)) at
#: u = x / delta: 1 at u -> 0, 0.85 at u = 1, 1/2 as u -> inf): records that all lie farther
#: (x_last > FOLD_U_SEEN delta) never see the pitchfork's own regime
FOLD_U_SEEN = 1.0
#: -2 log L by which a rival law must lose for the type to be named on records that cannot
#: show it directly: a likelihood ratio of 1e6 (ledger: "fold_indistinct")
DECISIVE = 2 * math.log(1e6)
#: least probability of the other exponent that withholds the type of a prediction
RIVAL_EXPONENT = 0.05
#: nearest static records the static law must fit at a mu* the eigenvalues allow (as many as
#: the engine's over-dispersion test of the static noise reads), and the level of that test
#: (ledger: "static_misfit")
STATIC_POINTS = 8
STATIC_ALPHA = 1e-3
_XATOL = 1e-12  # tolerance on log(mu* - mu_last): static records resolve mu* to ~1e-14


@dataclass(frozen=True)
class Evidence:
    """What the rules read: the sweep as given (``sw0``) and as fitted (``sw``: noise estimated
    or rescaled), the candidates' fits (best first), the free exponent ``a`` with its standard
    error, the damping regime, and the probabilities of the candidates."""

    sw0: Sweep
    sw: Sweep
    fits: Sequence[ModelFit]
    a: float = math.nan
    a_std: float = math.nan
    regime: str = "underdamped"
    probabilities: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Rule:
    """One withholding rule: ``check(transition, evidence)`` returns the flag's message when
    the named ``transition`` must be withheld (``None`` when not)."""

    code: str
    stage: str
    reason: str
    pinned_by: str
    check: Callable[[str, Evidence], str | None]
    #: what the type becomes when the rule fires (``"pitchfork"``: the exponent is decided, only
    #: the criticality is not)
    demote_to: str = "undetermined"


def _slowdown(transition: str, ev: Evidence) -> str | None:
    t_ratio = math.sqrt(float(ev.sw0.y[0] / ev.sw0.y[-1]))
    if t_ratio < MIN_T_RATIO and transition != "undetermined":
        return (
            f"T/T0 = {t_ratio:.3g} < {MIN_T_RATIO:g}: the critical slowing down has barely "
            "begun, the type is not named"
        )
    return None


def _fold_gap(sw: Sweep, fits: Sequence[ModelFit]) -> float:
    """How decisively the records exclude a fold against the best (conformal pitchfork) law
    ``fits[0]``: the eigenvalues' ``-2 log L`` gap of a fold law with as many parameters
    (:func:`fold_rival_gap`); with static data, the saddle-node candidate's ``-2 log L + BIC
    penalty`` over the best's, the same comparison that gives the probabilities (``inf``
    without a saddle-node candidate)."""
    if sw.w is None:
        return fold_rival_gap(sw, fits[0])
    fold = [f for f in fits if f.name == "saddle-node"]
    return fold[0].bic - fits[0].bic if fold else math.inf


def _fold_indistinct(transition: str, ev: Evidence) -> str | None:
    if "pitchfork" not in transition:
        return None
    top = ev.fits[0]
    delta = secondary_fold(ev.sw, top)
    x_last = float(top.profile.mu_star - ev.sw.mu[-1])
    pinned = delta <= x_last / (FOLD_U_MAX * (1 - 1e-6))
    if pinned or (x_last > FOLD_U_SEEN * delta and _fold_gap(ev.sw, ev.fits) < DECISIVE):
        return (
            f"the {top.name} law needs a secondary fold {delta:.3g} beyond mu*, "
            f"{'nearer than' if pinned else 'well inside'} the last record's distance "
            f"({x_last:.3g} before mu*): a fold explains the records as well, the type "
            "is not named"
        )
    return None


def _exponent_undecided(transition: str, ev: Evidence) -> str | None:
    top, fits = ev.fits[0], ev.fits
    if (
        transition != "undetermined"
        and ev.sw.w is None
        and top.corrections_exhausted
        and len(fits) > 1
        and fits[1].bic - top.bic < DECISIVE
    ):
        return (
            f"the {top.name} law needs all its corrections on the nearest {top.n} points and "
            f"beats the {fits[1].name} law by only {fits[1].bic - top.bic:.3g} in -2 log L "
            f"(< {DECISIVE:.3g}, a likelihood ratio of 1e6): without static data the type "
            "is not named"
        )
    return None


def _exponent_off(transition: str, ev: Evidence) -> str | None:
    a_hat, a_se = ev.a, ev.a_std
    if not (math.isfinite(a_se) and a_se > 0):
        return None
    cands = [0.25, 0.5] if ev.regime == "underdamped" else [0.5, 1.0]
    dist = min(abs(a_hat - c) for c in cands)
    if dist / a_se > 4 and dist > 0.05:
        return (
            f"free exponent a={a_hat:.3f}+-{a_se:.3f} is far from every candidate "
            f"({', '.join(f'{c:g}' for c in cands)}); a doubled exponent is the mark of "
            "over-damped data given as sigma2 = -omega^2 (give omega= instead)"
        )
    return None


def _rival_exponent(transition: str, ev: Evidence) -> str | None:
    if transition == "undetermined" or not ev.probabilities:
        return None
    p_fold = float(ev.probabilities.get("saddle-node", 0.0))
    rival = p_fold if "pitchfork" in transition else 1.0 - p_fold  # the other exponent a
    if rival >= RIVAL_EXPONENT:
        return (
            f"the data favour {transition}, but the other exponent keeps {rival:.2f} "
            f"(>= {RIVAL_EXPONENT:g}): the type is not named until more measurements decide it"
        )
    return None


def static_consistency(sw: Sweep, w_sd: np.ndarray, fit: ModelFit) -> tuple[float, int]:
    """How far the static records stray from the static law at a mu* the eigenvalues allow.

    The likelihood ratio ``D = min_mu* [chi2_sigma(mu*) + chi2_w(mu*)] - min_mu* chi2_sigma(mu*)``
    of ``fit``'s eigenvalue law (its corrections, on its ``n`` nearest points, noise as used)
    and the widest static series ``w = w* + sum_j g_j x^(j/2)``, ``j = 1..4`` (the b = 1/2 law
    with four corrections; it holds the smooth b = 1 law too) on the nearest ``STATIC_POINTS``
    records with their given noise ``w_sd``: under the law ``D`` is chi-square with
    ``STATIC_POINTS - 5`` degrees of freedom (returned with ``D``; ``(nan, 0)`` with too few
    records). ``mu*`` is shared, not fixed at the eigenvalues' estimate: static records are
    often far more precise than that estimate near mu* (the detector's static level to 1e-13
    where ``w - w*`` is 1e-3), so misfit read at a fixed mu* measures the eigenvalues' own error
    (ledger: "static_misfit")."""
    N = sw.mu.size
    m = min(N, STATIC_POINTS)
    dof = m - 5
    if sw.w is None or dof < 1 or N < fit.n:
        return math.nan, 0
    idx = slice(N - fit.n, N)
    idx_w = slice(N - m, N)
    scale = float(sw.mu[-1] - sw.mu[0])
    comp = _sigma_comp(sw, idx, 2 * fit.a, fit.h, fit.K, fit.conformal)
    cw = _Comp(sw.w[idx_w], 1.0 / w_sd[idx_w], _w_exps(0.5, 4), True, False, 0, False,
               sw.mu[idx_w])  # fmt: skip
    alone = _profile(sw.mu[idx], [comp], scale, with_interval=False, xatol=_XATOL).nll
    joint = _profile(sw.mu[idx], [comp, cw], scale, with_interval=False, xatol=_XATOL).nll
    return max(joint - alone, 0.0), dof


def _static_misfit(transition: str, ev: Evidence) -> str | None:
    sw, sw0 = ev.sw, ev.sw0
    if transition != "supercritical-pitchfork" or sw.w is None or sw0.w_sd is None:
        return None
    fit = next(f for f in ev.fits if f.name == transition)
    d, dof = static_consistency(sw, sw0.w_sd, fit)
    if dof and d > chi2_ppf(1 - STATIC_ALPHA, dof):
        return (
            "only the static deflection tells a supercritical pitchfork (b = 1/2) from a "
            f"subcritical one, but the nearest {dof + 5} static records miss the static law at "
            f"every mu* the eigenvalues allow (chi^2 = {d:.3g} for {dof} degrees of freedom, "
            f"beyond its {100 * (1 - STATIC_ALPHA):g} % quantile): the static exponent does not "
            "decide (an imperfect column's records far from its fold look alike); the type is "
            "not named"
        )
    return None


def _static_noise_unknown(transition: str, ev: Evidence) -> str | None:
    given = ev.sw0.w_sd is not None and ev.sw0.w_noise_given
    if transition != "supercritical-pitchfork" or ev.sw.w is None or given:
        return None
    return (
        "only the static deflection tells a supercritical pitchfork (b = 1/2) from a "
        "subcritical one, and an imperfect softening structure (which snaps at a fold) from "
        "both; the static records carry no noise level (give w_static_std), so their misfit "
        "about the static law cannot be read (a noise estimated from the same records absorbs "
        "it): named a pitchfork, its criticality not decided"
    )


RULES: tuple[Rule, ...] = (
    Rule("slowdown_not_reached", "classification",
         "far from mu* (T/T0 < 2.75) a fold and a pitchfork with a nearby secondary fold look "
         "alike",
         "tests/analysis/test_predict_lab.py::test_symmetric_early_stop_is_never_called_"
         "supercritical", _slowdown),
    Rule("fold_indistinct", "classification",
         "a pitchfork law whose secondary fold lies nearer mu* than the records is a fold in "
         "disguise unless a fold law loses decisively",
         "tests/analysis/test_predict_lab.py::test_fold_in_disguise_is_not_called_a_pitchfork",
         _fold_indistinct),
    Rule("exponent_undecided", "classification",
         "a law that needed every correction can follow the other exponent's records; without "
         "static data only a decisive likelihood ratio names the type",
         "tests/analysis/test_predict_lab.py::test_a_fold_read_as_a_pitchfork_far_from_mu_star_"
         "is_not_named", _exponent_undecided),
    Rule("exponent_off", "classification",
         "the free exponent is far from every candidate's: none of the laws holds",
         "tests/analysis/test_classify.py::test_exponent_far_from_candidates_is_undetermined",
         _exponent_off),
    Rule("static_misfit", "classification",
         "a supercritical pitchfork is told by its static exponent alone: not where the "
         "nearest static records miss the static law at every mu* the eigenvalues allow",
         "tests/structures/test_static_law_consistency.py", _static_misfit),
    Rule("static_noise_unknown", "classification",
         "a supercritical pitchfork (no snap) is named only from static records with a noise "
         "level: without one an imperfect softening structure's records pass the static law",
         "tests/structures/test_static_law_consistency.py::test_without_the_static_noise_an_"
         "imperfect_column_is_never_named_supercritical", _static_noise_unknown,
         demote_to="pitchfork"),
    Rule("type_withheld", "prediction",
         "the other exponent keeps >= 5 %: the type is not decided at the interval's 95 %",
         "tests/analysis/test_predict_lab.py::test_no_type_named_while_the_other_exponent_keeps_"
         "five_percent", _rival_exponent),
)  # fmt: skip


def withhold(transition: str, ev: Evidence, stage: str, flags: list[Flag]) -> str:
    """``transition``, or what a rule of ``stage`` that withholds it demotes it to
    (``"undetermined"``, or ``"pitchfork"`` where only the criticality is undecided); each rule
    that fires appends its flag, in the table's order."""
    for rule in RULES:
        if rule.stage != stage:
            continue
        msg = rule.check(transition, ev)
        if msg is not None:
            flags.append(Flag(rule.code, msg))
            transition = rule.demote_to
    return transition
