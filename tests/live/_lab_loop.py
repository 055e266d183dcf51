"""A lab that follows the advice: the structure, its lab and the loop, written once.

Used by tests/live/test_lab_in_the_loop.py (over HTTP with the SDK) and bench/lab_session.py
(in process, for the figure of docs/lab-guide.md). The records come from the independent
generator of ``tests/labrec`` (numpy alone: a fundamental that softens as a saddle-node or a
pitchfork, in degrees and seconds, with the hammer's contact, mains hum, higher modes and
noise, drawn per seed). This module imports neither ``sim`` nor ``service``: the door is a
callable the caller gives.

The lab starts far (0 deg, its step 4 deg, mu* drawn in 25..60 deg), records where the sweep
advises with the length and step it suggests (as far as its recorder allows: at most 30 s, a
sample step of at least 0.2 ms), and stops when the sweep says ``converged``, gives no safe
step, or after 30 records.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "labrec"))

import labfiles as F  # noqa: E402
import labgen as L  # noqa: E402

KINDS = ("saddle-node", "subcritical-pitchfork", "supercritical-pitchfork")
BUDGET = 30
STEP = 4.0  # deg: the lab's own step far from the transition
MAX_DURATION, MIN_DT = 30.0, 1 / 5000  # what the lab's recorder allows


@dataclass(frozen=True)
class Answer:
    """What the lab reads after one record: the door's update and the advice in it."""

    update: Any
    converged: bool
    next_control: float | None
    record_duration: float | None
    record_dt: float | None


def campaign(kind: str, seed: int) -> F.Campaign:
    """A softening structure and a lab, drawn from ``seed`` (the drift is off: today's detector
    picks the wrong mode on most records with drift, issue 27)."""
    rng = np.random.default_rng([seed, 29])
    lab = L.Lab(quantity="displacement", fs=2000.0, duration=4.0,
                pulse_s=float(rng.uniform(5e-3, 15e-3)), hum=float(rng.uniform(0.005, 0.03)),
                mains_hz=float(rng.choice([50.0, 60.0])), snr_db=float(rng.uniform(28.0, 40.0)),
                peak_mm=0.3)  # fmt: skip
    return F.Campaign(kind, float(rng.uniform(25.0, 60.0)), 0.0,
                      f1_hz=float(rng.uniform(6.0, 15.0)), lab=lab, seed=seed, ramp=0.0,
                      wobble=0.0, offset=0.0)  # fmt: skip


def missed_hammer(rec: L.LabRecord, seed: int) -> np.ndarray:
    """The record of a hammer that missed: the sensor's level and its noise alone."""
    rng = np.random.default_rng(seed)
    return float(np.median(rec.y)) + 0.01 * float(np.std(rec.y)) * rng.standard_normal(
        rec.y.size)


def _finite(x: float | None) -> bool:
    return x is not None and math.isfinite(x)


def follow(
    camp: F.Campaign,
    add: Callable[[int, np.ndarray, float, float], Answer],
    bad_at: int | None = None,
) -> list[Answer]:
    """Follow the advice from 0 deg; the answers after each record.

    ``add(k, y, dt, control)`` gives record ``k`` (0-based; its name is ``rec_<k>.csv``) to the
    sweep. Record ``bad_at`` is a missed hammer. Every control recorded is asserted below the
    generator's mu* (the issue's first criterion, on every record)."""
    mu, duration, dt, answers = 0.0, None, None, []
    for k in range(BUDGET):
        assert mu < camp.mu_star, f"advised {mu} at or past mu* = {camp.mu_star}"
        rec = camp.record(mu, k, duration=duration, dt=dt)
        y = missed_hammer(rec, k) if k == bad_at else rec.y
        a = add(k, y, rec.dt, mu)
        answers.append(a)
        if a.converged or not _finite(a.next_control):
            break
        mu = float(a.next_control)
        if _finite(a.record_duration) and _finite(a.record_dt):
            duration, dt = min(a.record_duration, MAX_DURATION), max(a.record_dt, MIN_DT)
        else:
            duration, dt = None, None
    return answers


@dataclass(frozen=True)
class ImperfectCampaign(F.Campaign):
    """A softening structure whose pitchfork is unfolded by an imperfection: it snaps at a fold.

    Its buckling amplitude ``q`` (the stable branch from ``q = 0`` far away) obeys the cusp
    ``x q - q^3 = eps`` with ``x = (mu_p - mu) / (mu_p - mu0)`` (``mu_p`` the perfect
    structure's pitchfork); the fundamental's stiffness is ``x - 3 q^2`` (times its value at
    ``mu0``), zero at the fold ``x_f = (3 sqrt(3) eps / 2)^(2/3)``. ``mu_star`` is the fold
    ``mu_p - x_f (mu_p - mu0)``, the value a lab must not reach; the static level follows ``q``.
    """

    mu_perfect: float = 42.0
    x_fold: float = 0.01

    @property
    def eps(self) -> float:
        return 2.0 * self.x_fold**1.5 / (3.0 * math.sqrt(3.0))

    def amplitude(self, mu: float) -> float:
        """``q`` on the stable branch at control ``mu`` (bisection to 1e-15)."""
        x = (self.mu_perfect - mu) / (self.mu_perfect - self.mu0)
        if mu >= self.mu_star or x <= self.x_fold:
            raise ValueError(f"control {mu} is at or past the fold {self.mu_star}")
        lo, hi = 0.0, math.sqrt(x / 3.0)  # x q - q^3 - eps: < 0 at 0, >= 0 at the stiffness's zero
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if x * mid - mid**3 - self.eps < 0.0:
                lo = mid
            else:
                hi = mid
            if hi - lo < 1e-15:
                break
        return 0.5 * (lo + hi)

    def modes(self, mu: float) -> L.Modes:
        q = self.amplitude(mu)
        x = (self.mu_perfect - mu) / (self.mu_perfect - self.mu0)
        w0 = 2 * math.pi * self.f1_hz * math.sqrt(x - 3.0 * q * q)
        f = [w0 / (2 * math.pi)] + [h[0] for h in self.higher]
        z = [self.gamma / w0] + [h[1] for h in self.higher]
        return L.Modes(tuple(f), tuple(z), (1.0,) + tuple(h[2] for h in self.higher))

    def static(self, mu: float) -> float:
        q_fold = math.sqrt(self.x_fold / 3.0)
        return self.static_c + self.static_s * self.amplitude(mu) / q_fold


def imperfect_campaign(seed: int) -> ImperfectCampaign:
    """The lab of :func:`campaign` on an imperfect softening pitchfork: the perfect structure's
    pitchfork drawn in 25..60 deg, the fold 0.5-3 % of the distance before it."""
    base = campaign("subcritical-pitchfork", seed)
    rng = np.random.default_rng([seed, 28])
    mu_p, x_f = base.mu_star, float(rng.uniform(0.005, 0.03))
    fields = {f: getattr(base, f) for f in base.__dataclass_fields__}
    fields.update(mu_star=mu_p - x_f * (mu_p - base.mu0), mu_perfect=mu_p, x_fold=x_f)
    return ImperfectCampaign(**fields)
