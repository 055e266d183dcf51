"""What the imperfect pitchforks change in an answer (:func:`decide`).

The perfect laws' answer (mu*, its interval, the type and its probabilities) is weighed against
the perfect and imperfect pitchforks fitted on the nearest points (:mod:`.cusp`'s
:class:`~.cusp.Imperfection`): an imperfection the records establish is told (a softening one
snaps at its fold, named a saddle-node; a stiffening one never loses stability, ``none``) or,
where its kind is not told, the type is withheld; one they do not establish only widens the
interval down to the earliest fold the softening law allows. docs/predictor.md gives each
threshold's calibration (the ledger).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scipy import special

from service.analysis.common import Flag
from service.analysis.predictor._dist import chi2_ppf, norm_ppf
from service.analysis.predictor.cusp import _ALPHA, ESTABLISHED, Imperfection

__all__ = ["Verdict", "decide"]

MAX_CORRECTION = 2.0  # largest departure of a told stiffening law's corrections from 1
#: ... and by which one imperfect law must beat the other for its kind (softening: a snap at a
#: fold; stiffening: no loss of stability) to be told (a likelihood ratio of 100)
TOLD = 2 * math.log(100.0)
#: -2 log L gain (chi-square 95 % of one parameter) from which a softening imperfection the
#: perfect answer ignores is said: the interval then reaches down to the earliest fold allowed
LEANS = float(chi2_ppf(0.95, 1))


@dataclass(frozen=True)
class Verdict:
    """What the imperfect laws change in an answer.

    ``transition`` None: the type is the perfect answer's (possibly withheld by ``flags``);
    ``probabilities`` None: the perfect answer's. ``least_sigma2``/``least_mu``: the least
    ``|sigma^2|`` of a stiffening imperfect structure and the control where it occurs."""

    mu_star: float
    lo: float
    hi: float
    std: float
    transition: str | None
    probabilities: dict[str, float] | None
    a: float | None
    flags: tuple[Flag, ...]
    least_sigma2: float = math.nan
    least_mu: float = math.nan
    decided: bool = False


def _stiff_told(imp: Imperfection, es: float, et: float) -> bool:
    """Whether the stiffening imperfection is established (gain ``et`` >= :data:`ESTABLISHED`)
    and told from the softening one (by :data:`TOLD`), by its own stiffness (its least
    stiffness within the window, corrections within :data:`MAX_CORRECTION`)."""
    t = imp.stiff
    return (et >= ESTABLISHED and et - es >= TOLD and t.mu_p >= imp.first
            and t.correction <= MAX_CORRECTION)  # fmt: skip


def _cusp_fold(imp: Imperfection) -> bool:
    """Whether the softening cusp law holds on its window and beats, each by
    :data:`ESTABLISHED`, the perfect pitchfork and the perfect fold law on the same points,
    and the stiffening law by :data:`TOLD` (the records' own noise; the perfect engine's
    rescaled noise would hide the difference)."""
    s = imp.soft
    return (imp.fits and imp.nll_perfect - s.nll >= ESTABLISHED
            and imp.nll_fold - s.nll >= ESTABLISHED and imp.stiff.nll - s.nll >= TOLD)


def _cusp_none(imp: Imperfection) -> bool:
    """Whether the stiffening cusp law holds on its window, beats the perfect pitchfork and
    the perfect fold law each by :data:`ESTABLISHED` and the softening law by :data:`TOLD`, by
    its own stiffness (its least stiffness within or beyond the window, corrections within
    :data:`MAX_CORRECTION`)."""
    t = imp.stiff
    return (imp.fits and imp.nll_perfect - t.nll >= ESTABLISHED
            and imp.nll_fold - t.nll >= ESTABLISHED and imp.soft.nll - t.nll >= TOLD
            and t.mu_p >= imp.first and t.correction <= MAX_CORRECTION)  # fmt: skip


def _fold_fails(imp: Imperfection) -> bool:
    """Whether, on a window where one law holds, the perfect fold law misfits (chi-square at
    :data:`_ALPHA`), a pitchfork law (perfect or imperfect) beats it by :data:`ESTABLISHED`
    and the softening cusp (a snap at a fold) is not told from the stiffening one by
    :data:`TOLD`: a fold named elsewhere is then not told from a structure that never loses
    stability."""
    best = min(imp.nll_perfect, imp.soft.nll, imp.stiff.nll)
    dof = max(imp.window - imp.K - 2, 1)
    return (imp.fits and imp.nll_fold - best >= ESTABLISHED
            and imp.stiff.nll - imp.soft.nll < TOLD
            and bool(special.chdtrc(dof, imp.nll_fold) < _ALPHA))  # fmt: skip


def _fold_withheld(
    imp: Imperfection, answer: tuple[float, ...], shared: dict[str, float], detail: str
) -> Verdict:
    """The perfect laws' fold kept with its interval, its name withheld: a stiffening
    imperfection (no loss of stability) explains the records better."""
    m, std, lo, hi = answer
    return Verdict(
        m, lo, hi, std, "undetermined", shared, None,
        (Flag("imperfection_undecided", f"{detail}: the perfect laws name a fold, but an "
              "imperfect stiffening pitchfork (no loss of stability) explains the records "
              "better: the type is not named; the interval is the fold's"),),
        decided=True,
    )  # fmt: skip


def decide(
    imp: Imperfection, transition: str, probs: dict[str, float], answer: tuple[float, ...],
    level: float, misfit: bool = True,
) -> Verdict:
    """The answer once the imperfect laws are weighed: ``answer = (mu*, std, lo, hi)`` and
    ``transition`` / ``probs`` are the perfect laws'; ``misfit``: whether the perfect laws
    misfit their records (flags ``law_misfit``, ``noise_underestimated``, ``poor_fit``,
    ``exponent_off``). Where they do not, the imperfect laws only widen the interval: a gain
    over the plain perfect pitchfork is then no evidence (the beam's symmetric pitchfork,
    whose secondary fold the perfect engine's conformal law knows, was read as a softening
    imperfection in 291 of 300 calibration plans).

    * imperfection established (gain >= :data:`ESTABLISHED`) and one kind told (by
      :data:`TOLD`): softening -> a snap at the fold, ``"saddle-node"``, mu* the fold and its
      interval; stiffening -> ``"none"`` (no loss of stability), mu* the least stiffness's
      control and its interval;
    * established but the kind not told: the type withheld (``imperfection_undecided``), the
      interval reaching the softening law's fold;
    * not established: the perfect answer, its interval reaching down to the earliest fold the
      softening law allows (its profile interval); a snap withheld where the stiffening law
      beats both others by :data:`LEANS` (and the perfect laws do not name a fold).
    """
    es, et = imp.evidence_soft, imp.evidence_stiff
    w = imp.weights
    # per transition: a softening imperfect pitchfork snaps at a fold (a saddle-node), a
    # stiffening one never loses stability ("none"); the perfect laws share the rest
    shared = {k: v * w["perfect"] for k, v in probs.items()}
    shared["saddle-node"] = shared.get("saddle-node", 0.0) + w["imperfect-softening"]
    shared["none"] = w["imperfect-stiffening"]
    detail = (f"the imperfect softening law gains {es:.3g} and the stiffening one {et:.3g} in "
              f"-2 log L over the perfect pitchfork on the nearest {imp.window} points")
    if not misfit:
        es, et = min(es, 0.5 * LEANS), 0.0
    # the gains that may withhold a fold the perfect laws name (never name anything): where no
    # law holds on the window, over the best law's own reduced chi-square
    phi = 1.0 if imp.fits else max(imp.misfit_ratio, 1.0)
    es_fold, et_fold = es / phi, et / phi
    if not imp.fits:
        # no law holds on any window: a gain over a misfitting perfect law tells nothing (the
        # beam's antisymmetric sequential protocol, far from mu*: both imperfect laws 1.4e4
        # ahead of the perfect one, the stiffening law "told" with a zero-width interval; on
        # the beam's antisymmetric records with static data one kind alone gains 1e2-4e6,
        # the other nothing)
        es, et = 0.0, 0.0
    if probs.get("saddle-node", 0.0) >= 0.9:
        return _fold_named(imp, answer, level, shared, detail, misfit, es_fold, et_fold)
    t = imp.stiff
    if et > es and (t.mu_p < imp.first or not t.correction <= MAX_CORRECTION):
        # a least stiffness before every record of the window, or corrections that change the
        # law by more than MAX_CORRECTION: they, not the law's stiffness, follow the records
        # (a softening column's falling records were read as a stiffening law's rise with a
        # correction turning it over): never told
        et = min(et, es + 0.5 * TOLD)
    if max(es, et) >= ESTABLISHED and abs(es - et) >= TOLD:
        return _told(imp, transition, probs, answer, level, shared, detail, es, et)
    if max(es, et) >= ESTABLISHED:
        return _kind_untold(imp, answer, level, shared, detail)
    return _not_established(imp, transition, answer, level, detail, es, et)


def _fold_named(
    imp: Imperfection, answer: tuple[float, ...], level: float, shared: dict[str, float],
    detail: str, misfit: bool, es_fold: float, et_fold: float,
) -> Verdict:
    """:func:`decide` where the perfect laws name a fold (p >= 0.9): ``es_fold``/``et_fold``
    the gains read against the window's misfit."""
    m, std, lo, hi = answer
    z = float(norm_ppf(0.5 + level / 2))
    s, t = imp.soft, imp.stiff
    # a fold the perfect laws name keeps their answer: never read as "no loss of
    # stability" (the beam's fold on the sequential protocol was called none by a
    # stiffening law with corrections), and its interval is the fold law's own (widening it
    # to the cusp law's fold moved warn's steps on the asymmetric beam: error 1.09e-4 for
    # the 1e-4 it reaches); an imperfect column named a fold 0.5 % before it can then be
    # late (1 of 40 plans of bench/structures.py). Only its name is withheld where a
    # stiffening imperfection is told (no loss of stability: never a confident snap)
    if misfit and _cusp_none(imp) and shared["none"] >= 0.9:
        # the stiffening cusp law holds and beats the fold law itself decisively: the
        # records' fall is a stiffness that is least and rises again, no fold
        return Verdict(
            t.mu_p, t.lo, t.hi, 0.5 * (t.hi - t.lo) / z, "none", shared, 0.5, (
                Flag("no_loss_of_stability", f"{detail}, and {imp.nll_fold - t.nll:.3g} over "
                     f"the fold law: an imperfect stiffening pitchfork (G = {t.G:.3g}) that "
                     f"never loses stability; its least stiffness, |sigma2| = "
                     f"{t.least_sigma2:.6g}, at mu = {t.mu_p:.6g} (the interval is that "
                     "point's)"),),
            least_sigma2=t.least_sigma2, least_mu=t.mu_p, decided=True,
        )  # fmt: skip
    if _stiff_told(imp, es_fold, et_fold):
        return _fold_withheld(imp, answer, shared, detail)
    if misfit and _fold_fails(imp):
        return Verdict(m, lo, hi, std, "undetermined", shared, None, (
            Flag("imperfection_undecided", f"{detail}: the perfect laws name a fold, but on "
                 f"these points the fold law misfits (-2 log L {imp.nll_fold:.3g}) where a "
                 "pitchfork law fits better, and whether it softens (a snap) or stiffens (no "
                 "loss of stability) is not told: the type is not named; the interval is "
                 "the fold's"),
        ), decided=True)  # fmt: skip
    if _cusp_fold(imp) and s.lo < lo:
        # the softening cusp's fold explains the records decisively better than the fold
        # law itself (the crossover from a = 1/2 to 1/4): the interval reaches its fold
        # too (an imperfect column named a fold 0.5 % before it had been late); the
        # headline stays the fold law's (on 2 of 50 beam folds the cusp's fold was 3x
        # further from the truth)
        lo2, hi2 = s.lo, max(hi, s.hi)
        return Verdict(m, lo2, hi2, max(std, 0.5 * (hi2 - lo2) / z), None, None, None, (
            Flag("imperfect_softening", f"{detail}, and {imp.nll_fold - s.nll:.3g} over the "
                 f"fold law: an imperfect softening pitchfork (G = {s.G:.3g}) may snap at "
                 f"its fold, {s.mu_p:.6g}; the interval reaches it"),
        ))  # fmt: skip
    return Verdict(m, lo, hi, std, None, None, None, ())


def _told(
    imp: Imperfection, transition: str, probs: dict[str, float], answer: tuple[float, ...],
    level: float, shared: dict[str, float], detail: str, es: float, et: float,
) -> Verdict:
    """:func:`decide` where an imperfection is established and its kind told (softening by
    ``es > et``)."""
    m, std, lo, hi = answer
    z = float(norm_ppf(0.5 + level / 2))
    s, t = imp.soft, imp.stiff
    if es > et and probs.get("saddle-node", 0.0) >= 0.9:
        # a fold the perfect laws already name: their answer (the fold's own law) stands,
        # its interval reaching the cusp law's fold too
        lo2, hi2 = min(lo, s.lo), max(hi, s.hi)
        return Verdict(m, lo2, hi2, max(std, 0.5 * (hi2 - lo2) / z), None, None, None, (
            Flag("imperfect_softening", f"{detail}: a fold, as the perfect laws say; the "
                 f"interval reaches the imperfect law's fold ({s.lo:.6g} to {s.hi:.6g})"),
        ))  # fmt: skip
    f = s if es > et else t
    if es > et:
        name, fl = "saddle-node", Flag(
            "imperfect_softening",
            f"{detail}: an imperfect softening pitchfork (G = {s.G:.3g}, its perfect "
            f"mu* {s.mu_star:.6g}) that snaps at the fold mu_f = {s.mu_p:.6g} before mu*; "
            "the interval is the fold's",
        )
    else:
        name, fl = "none", Flag(
            "no_loss_of_stability",
            f"{detail}: an imperfect stiffening pitchfork (G = {t.G:.3g}) that never loses "
            f"stability; its least stiffness, |sigma2| = {t.least_sigma2:.6g}, at mu = "
            f"{t.mu_p:.6g} (the interval is that point's)",
        )
    p_named = shared[name]
    flags = [fl]
    decided = p_named >= 0.9
    if not decided:
        flags.append(Flag("imperfection_undecided", f"{detail}: {f.law} has probability "
                          f"{p_named:.2f} < 0.9, the type is not named"))  # fmt: skip
    p_pf = sum(v for k, v in probs.items() if "pitchfork" in k)
    if p_pf >= 0.9 and es > et:
        # the perfect laws name a pitchfork: the records cannot tell a perfect pitchfork
        # with far corrections from an imperfect one (the beam's antisymmetric plans far
        # from mu* were read as softening imperfections): the type withheld, the interval
        # both answers'
        lo2, hi2 = min(lo, f.lo, s.lo), max(hi, f.hi)
        return Verdict(m, lo2, hi2, max(std, 0.5 * (hi2 - lo2) / z), "undetermined", None,
                       None, (fl, Flag("imperfection_undecided", f"{detail}: the perfect "
                                       f"laws name a {transition or 'pitchfork'} "
                                       f"(p = {p_pf:.2f}): whether the structure is perfect "
                                       "is not told, the type is not named; the interval "
                                       "holds both answers")),
                       decided=True)  # fmt: skip
    f_lo, f_hi = f.lo, f.hi
    if es > et and probs.get("saddle-node", 0.0) >= 0.05:
        # the perfect fold law holds there too (a generic fold is no cusp far from it):
        # the interval is both laws' (each misses the other's truncation)
        f_lo, f_hi = min(f_lo, lo), max(f_hi, hi)
    return Verdict(
        f.mu_p, f_lo, f_hi, 0.5 * (f_hi - f_lo) / z, name if decided else "undetermined",
        shared, 0.25 if es > et else 0.5, tuple(flags),
        least_sigma2=t.least_sigma2 if name == "none" else math.nan,
        least_mu=t.mu_p if name == "none" else math.nan, decided=True,
    )  # fmt: skip


def _kind_untold(
    imp: Imperfection, answer: tuple[float, ...], level: float, shared: dict[str, float],
    detail: str,
) -> Verdict:
    """:func:`decide` where an imperfection is established but its kind is not told."""
    m, std, lo, hi = answer
    z = float(norm_ppf(0.5 + level / 2))
    s = imp.soft
    lo2, hi2 = min(lo, s.lo), max(hi, s.hi)
    m2 = m if lo2 <= m <= hi2 else s.mu_p
    return Verdict(
        m2, lo2, hi2, max(std, 0.5 * (hi2 - lo2) / z), "undetermined", shared, None,
        (Flag("imperfection_undecided", f"{detail}: the records are not those of a perfect "
              "structure, but whether it softens (a snap at a fold before mu*) or stiffens "
              "(no loss of stability) is not told; the interval reaches the softening "
              f"law's fold ({s.lo:.6g} to {s.hi:.6g})"),),
        decided=True,
    )  # fmt: skip


def _not_established(
    imp: Imperfection, transition: str, answer: tuple[float, ...], level: float, detail: str,
    es: float, et: float,
) -> Verdict:
    """:func:`decide` where no imperfection is established: the perfect answer, its interval
    reaching the softening law's earliest fold, a snap withheld where the stiffening law
    leans."""
    m, std, lo, hi = answer
    z = float(norm_ppf(0.5 + level / 2))
    s = imp.soft
    fl: list[Flag] = []
    tr = None
    # an imperfection the records do not establish widens by its fits' statistical intervals
    # only: the truncation's bias of a law with no evidence (a barely identified fit with one
    # more correction) stopped the beam's antisymmetric warn at T/T0 = 1.6, its interval
    # reaching 0.8 for records stable to 1.17 and mu* = 2
    s_lo = s.lo_fits if math.isfinite(s.lo_fits) else s.lo
    if s_lo < lo:
        fl.append(Flag("imperfection_possible", f"{detail}: a softening imperfection is not "
                       f"excluded, its fold may come as early as {s_lo:.6g}; the interval "
                       "reaches it"))  # fmt: skip
        # the type stays: short of an established imperfection, the softening law's gain
        # over a misfitting perfect law is no evidence (withholding a supercritical type at a
        # gain of chi2(0.95, 1) withheld 17 of 100 of the beam's antisymmetric plans)
    if et >= es + LEANS and transition in ("saddle-node", "subcritical-pitchfork"):
        # a snap named while a stiffening imperfection (no loss of stability) fits better than
        # the perfect law and the softening one (a fold's own records favour the softening law)
        tr = "undetermined"
        fl.append(Flag("imperfection_undecided", f"{detail}: the {transition} named snaps, an "
                       "imperfect stiffening structure never loses stability: the type is not "
                       "named"))  # fmt: skip
    if fl:
        lo2 = min(lo, s_lo)
        return Verdict(m, lo2, hi, max(std, 0.5 * (hi - lo2) / z), tr, None, None, tuple(fl))
    return Verdict(m, lo, hi, std, None, None, None, ())
