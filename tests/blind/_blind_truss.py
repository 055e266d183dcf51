"""A two-bar (von Mises) truss whose joints have friction: a snap-through with amplitude-
dependent damping (tests/blind only; numpy and scipy, never ``sim`` or ``service``).

Structure (:class:`FrictionTruss`): two elastic bars of axial stiffness ``EA`` and stress-free
length ``L0 = sqrt(b^2 + h0^2)`` meet at an apex of mass ``m`` at height ``h`` above their
supports (half-span ``b``); a dead load ``P`` pushes the apex down. With ``L(h) = sqrt(b^2 +
h^2)`` the potential is ``V = EA (L - L0)^2 / L0 + P h``, so on the equilibrium path

    P(h) = 2 EA h (1/L - 1/L0),        V''(h) = 2 EA (1/L0 - b^2 / L^3),

and the stiffness vanishes at ``L_c^3 = b^2 L0`` (closed form): a symmetric limit point, the
truss snaps through (saddle-node) at ``P_c = P(h_c)``, ``h_c = sqrt(L_c^2 - b^2)``. Beyond it
the apex rests on the inverted branch ``h < -h0`` (where ``P(h) = P`` again, stiff).

Joint friction (:func:`friction_response`): the apex's small motion about its equilibrium is
``x'' + 2 gamma x' + omega0^2 x = -f sign(x')`` (Coulomb friction ``f``, an acceleration, plus a
little viscous damping), kicked by an impulse (initial velocity ``v0``). Between two turning
points the motion is a damped oscillation about the shifted centre ``-f sign(x') / omega0^2``;
the first turning point is at ``tan(omega_d t1) = v0 omega_d / (omega0^2 X0 + gamma v0)``, every
later one half a damped period after the previous; the apex sticks at the first turning point
with ``omega0^2 |x| <= f``. Everything is closed form; the decay of the envelope is linear (not
exponential) and its apparent damping grows as the amplitude falls, while the frequency of the
motion is exactly ``omega_d`` throughout: the critical mode's ``sigma^2 = -omega0^2`` stays the
truth. Near the snap ``omega0`` falls at a fixed ``f``: fewer cycles before the apex sticks, and
it sticks up to ``f / omega0^2`` away from its equilibrium (the laser's level after the ring-down
is not the one before the hit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from _blind_structures import State, _brent


@dataclass(frozen=True)
class FrictionTruss:
    """Von Mises truss (module docstring), non-dimensional: ``b = EA = m = 1`` by default."""

    h0: float = 0.2
    b: float = 1.0
    ea: float = 1.0
    m: float = 1.0

    @property
    def l0(self) -> float:
        return math.hypot(self.b, self.h0)

    def length(self, h: float) -> float:
        return math.hypot(self.b, h)

    def load(self, h: float) -> float:
        """The dead load that holds the apex at height ``h``."""
        return 2.0 * self.ea * h * (1.0 / self.length(h) - 1.0 / self.l0)

    def potential(self, h: float, p: float) -> float:
        return self.ea * (self.length(h) - self.l0) ** 2 / self.l0 + p * h

    def stiffness(self, h: float) -> float:
        """``V''(h)`` (independent of the load)."""
        return 2.0 * self.ea * (1.0 / self.l0 - self.b**2 / self.length(h) ** 3)

    def h_critical(self) -> float:
        lc = (self.b**2 * self.l0) ** (1.0 / 3.0)
        return math.sqrt(lc * lc - self.b**2)

    def critical_load(self) -> float:
        """``P_c`` in closed form."""
        return self.load(self.h_critical())

    def critical_load_by_maximum(self) -> float:
        """``P_c`` a second way: the largest load on the path ``h in (0, h0)`` (bounded scalar
        minimisation of ``-P(h)``), for the tests."""
        from scipy import optimize

        r = optimize.minimize_scalar(lambda h: -self.load(h), bounds=(1e-9, self.h0),
                                     method="bounded", options={"xatol": 1e-13})  # fmt: skip
        return -float(r.fun)

    def kind(self) -> str:
        return "saddle-node"

    def equilibrium(self, p: float) -> float:
        """The apex height on the primary path (``h_c < h <= h0``) under ``p < P_c``."""
        if p == 0.0:
            return self.h0
        return _brent(lambda h: self.load(h) - p, self.h_critical(), self.h0)

    def remote_equilibrium(self, p: float) -> float:
        """The apex height on the inverted path (``h < -h0``) under ``p > 0``."""
        hi = -self.h0
        lo = hi - 1.0
        while self.load(lo) < p:
            lo = hi - 2.0 * (hi - lo)
        return _brent(lambda h: self.load(h) - p, lo, hi)

    def state(self, p: float, remote: bool = False) -> State:
        h = self.remote_equilibrium(p) if remote else self.equilibrium(p)
        k = self.stiffness(h) / self.m
        one = np.ones(1)
        # the laser reads the apex's downward deflection from its unloaded height
        return State(np.array([k]), one, one, self.h0 - h, 0,
                     "remote" if remote else "primary")  # fmt: skip


def first_turn(omega0: float, gamma: float, v0: float, f: float) -> float:
    """The first turning point's time after the kick (from rest at the equilibrium, velocity
    ``v0 > 0``; centre ``-f / omega0^2``): the root in ``(0, pi / omega_d)`` of ``x'(t) = 0``."""
    wd = math.sqrt(omega0 * omega0 - gamma * gamma)
    x0 = f / (omega0 * omega0)  # the start relative to the centre
    return math.atan2(v0 * wd, omega0 * omega0 * x0 + gamma * v0) / wd


def turning_points(omega0: float, gamma: float, v0: float, f: float,
                   t_end: float) -> list[tuple[float, float, float]]:  # fmt: skip
    """``[(t_start, x_start, centre), ...]``: each sliding segment (the last one ends when the
    apex sticks, its centre then being its own position: at rest)."""
    wd = math.sqrt(omega0 * omega0 - gamma * gamma)
    w2 = omega0 * omega0
    c = -f / w2
    segs = [(0.0, 0.0, c)]
    t1 = first_turn(omega0, gamma, v0, f)
    xc0 = -c
    x1 = c + math.exp(-gamma * t1) * (xc0 * math.cos(wd * t1)
                                      + (v0 + gamma * xc0) / wd * math.sin(wd * t1))  # fmt: skip
    t, x = t1, x1
    half = math.pi / wd
    while t < t_end:
        if w2 * abs(x) <= f:  # the spring cannot overcome static friction: it sticks
            segs.append((t, x, x))
            break
        c = math.copysign(f / w2, x)
        segs.append((t, x, c))
        x = c - (x - c) * math.exp(-gamma * half)
        t += half
    return segs


def friction_response(t: np.ndarray, omega0: float, gamma: float, v0: float,
                      f: float) -> np.ndarray:  # fmt: skip
    """The apex's displacement about its equilibrium at the times ``t`` after the kick (zero
    before): the closed form of the module docstring."""
    t = np.asarray(t, float)
    y = np.zeros(t.shape)
    wd = math.sqrt(omega0 * omega0 - gamma * gamma)
    segs = turning_points(omega0, gamma, v0, f, float(np.max(t)) if t.size else 0.0)
    bounds = [s[0] for s in segs[1:]] + [math.inf]
    for (ts, xs, c), te in zip(segs, bounds, strict=True):
        on = (t >= ts) & (t < te)
        if not on.any():
            continue
        tau = t[on] - ts
        if ts == 0.0:  # the kick: from the equilibrium with velocity v0
            xc = xs - c
            y[on] = c + np.exp(-gamma * tau) * (xc * np.cos(wd * tau)
                                                + (v0 + gamma * xc) / wd * np.sin(wd * tau))
        elif xs == c:  # stuck
            y[on] = c
        else:  # from rest at a turning point
            xc = xs - c
            y[on] = c + xc * np.exp(-gamma * tau) * (np.cos(wd * tau)
                                                     + gamma / wd * np.sin(wd * tau))
    return y


def record_friction(state: State, omega_scale: float, gamma: float, rec, v0: float, f: float,
                    static_mm_per_unit: float = 1.0, adc_range: float | None = None):  # noqa: ANN001, ANN201  # fmt: skip
    """One kick of the truss with joint friction recorded as ``_blind_recorder.record`` records
    a linear structure (same impairments, same file), the hammer an impulse: ``v0`` (mm/s) and
    ``f`` (mm/s^2) from :meth:`_blind_sweeps.Campaign.friction`. A laser only (the friction
    response is a displacement)."""
    from _blind_recorder import Record, finish, sample_jitter

    if rec.sensor != "laser":
        raise ValueError("the friction truss is recorded with a laser")
    rng = np.random.default_rng(rec.seed)
    n = int(round(rec.duration_s * rec.rate_hz)) + 1
    t = np.arange(n) / rec.rate_hz
    t_hit = rec.pretrigger * rec.duration_s if rec.start == "pretrigger" else -rec.midring_s
    t_true = t + sample_jitter(rec, n)
    om2 = float(state.omega2[0]) * omega_scale**2
    if om2 <= gamma * gamma:
        raise ValueError("the friction truss is recorded underdamped only")
    y = friction_response(t_true - t_hit, math.sqrt(om2), gamma, v0, f)
    vals, vunit, quantity, peak = finish(y, t_true, state.static * static_mm_per_unit, rec, rng,
                                         adc_range=adc_range)  # fmt: skip
    t_file = (t_true if rec.jitter_stamped else t) * (1e3 if rec.time_unit == "ms" else 1.0)
    info = {"omega2_all": [om2], "peak": peak, "friction": f, "v0": v0,
            "segments": len(turning_points(math.sqrt(om2), gamma, v0, f, float(t[-1] - t_hit)))}
    return Record(t_file, vals, rec.time_unit, vunit, quantity, math.sqrt(om2), gamma, info)
