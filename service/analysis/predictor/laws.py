"""The laws the predictor fits, as values in one table (:data:`LAWS`).

A law says how the fundamental's undamped eigenvalue (and, when given, the static deflection)
approach the transition along the measured stable branch, ``x = mu* - mu > 0``:

    |sigma^2| = x^(2a) sum_k c_k x^(k h),        w = w* + sum_j g_j x^(b + j h)

(paper, Sec. "Asymptotic analysis"; eqs. saddleGrowthRate, pitchforkGrowthRate,
saddleEquilibriums, pitchforkEquilibriums, with regular corrections). ``family`` tells which
engine fits it: ``"power"`` laws by the profile-likelihood engine
(:mod:`.compare`), ``"cusp"`` laws (the unfolded pitchfork of an
imperfect structure) by :mod:`.imperfect`.

Adding a law is one row here and, for a new family, one module that fits it.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["CANDIDATES", "LAWS", "Law", "law"]


@dataclass(frozen=True)
class Law:
    """One law of the table.

    Attributes
    ----------
    name : str
        The transition it names (the wire's type vocabulary).
    a : float
        Time exponent: ``sqrt|sigma^2| ~ x^a`` near the point it predicts.
    b : float or None
        Static exponent ``|w - w*| ~ x^b`` (None: the law says nothing of w).
    h : float
        Step of the regular corrections in powers of ``x`` (1/2 near a fold, 1 near a pitchfork).
    family : str
        ``"power"`` (a perfect normal form) or ``"cusp"`` (an imperfect pitchfork).
    predicts : str
        What its ``mu*`` is: the point a lab must not cross.
    loses_stability : bool
        Whether the measured branch loses stability at the point it predicts (a snap or a
        buckling) or not at all.
    """

    name: str
    a: float
    b: float | None
    h: float
    family: str
    predicts: str
    loses_stability: bool = True


LAWS: tuple[Law, ...] = (
    Law("saddle-node", 0.25, 0.5, 0.5, "power", "the fold where the branch ends (snap)"),
    Law("subcritical-pitchfork", 0.5, 1.0, 1.0, "power",
        "the pitchfork where the branch loses stability (snap)"),
    Law("supercritical-pitchfork", 0.5, 0.5, 1.0, "power",
        "the pitchfork where the structure buckles smoothly onto a side branch"),
    Law("imperfect-softening", 0.5, None, 1.0, "cusp",
        "the fold mu_f < mu* where an imperfect softening pitchfork snaps (named a saddle-node; "
        "a = 1/2 far from it, 1/4 near)"),
    Law("imperfect-stiffening", 0.5, None, 1.0, "cusp",
        "no loss of stability (named none): the control of least stiffness",
        loses_stability=False),
)  # fmt: skip

#: The perfect (power) laws the profile-likelihood engine compares: name -> (a, b, h)
CANDIDATES: dict[str, tuple[float, float, float]] = {
    lw.name: (lw.a, float(lw.b), lw.h)  # type: ignore[arg-type]
    for lw in LAWS
    if lw.family == "power"
}


def law(name: str) -> Law:
    """The law of the table named ``name`` (KeyError when none)."""
    for lw in LAWS:
        if lw.name == name:
            return lw
    raise KeyError(name)
