"""Lab plans on the independent structures: sweep tables (and impulse records) with their truth.

A plan is what an experimenter does without knowing the critical load: a fixed grid of loads
``mu_j = mu_last - j h`` (``mu_j >= 0``; coarse steps ``h / P_ref`` in [0.02, 0.1], fine ones
in [0.004, 0.02], at most 40 points) that stops at ``mu_last = P_ref (1 - d)``, ``d``
log-uniform in [1e-3, 1e-1]; ``P_ref`` is the load the lab must not cross (the fold of an
imperfect softening column, ``P_c`` of a perfect one, the truss's snap load) or, for a
stiffening imperfect column that never loses stability, its perfect ``P_c``. At each load the
fundamental's ``omega^2`` (exact, :mod:`_struct_models`) with relative Gaussian noise ``r``
(log-uniform in [1e-5, 1e-3]) handed over as ``sigma2 = -omega^2`` or as ``omega`` (with or
without its std), and in half of the plans the static level (angle or deflection) with noise
``r max(|q|, 1e-3 L)`` and its std.

The columns and their names are the product's sweep table: ``mu, sigma2[, sigma2_std]
[, w_static[, w_static_std]]`` or ``mu, omega[, omega_std]...`` (``damping`` beside an omega
table whose slow rows are over-damped).

Imports numpy only (and the models): nothing of the product.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from _struct_models import (
    AsymmetricTruss,
    CoupledColumns,
    LinkColumn,
    VonMisesTruss,
    coupled_least_stiffness,
)

KINDS = (
    "perfect-softening",
    "perfect-stiffening",
    "imperfect-softening",
    "imperfect-stiffening",
    "truss",
    "truss-asymmetric",
    "coupled-softening",
    "coupled-stiffening",
)
INPUTS = ("sigma2", "sigma2-no-std", "omega", "omega-no-std")
#: the truth's transition: what a lab sees at the load it must not cross
TRANSITION = {
    "perfect-softening": "subcritical-pitchfork",
    "perfect-stiffening": "supercritical-pitchfork",
    "imperfect-softening": "saddle-node",  # it snaps at a limit point (the fold) before P_c
    "imperfect-stiffening": "none",  # no loss of stability
    "truss": "saddle-node",
    "truss-asymmetric": "saddle-node",
    "coupled-softening": "saddle-node",  # two imperfect columns joined by a spring
    "coupled-stiffening": "none",
}


@dataclass(frozen=True, eq=False)
class Plan:
    """One lab plan and its truth.

    Attributes
    ----------
    index, kind, family : int, str, str
        Plan number, one of :data:`KINDS`, and the model (``"column-rotational"``,
        ``"column-lateral"`` or ``"truss"``).
    mu : ndarray, shape (n,)
        Loads (N), increasing.
    sigma2, sigma2_std, omega, omega_std, w_static, w_static_std : ndarray or None
        The table's columns as handed over (None where absent).
    damping : float or None
        ``xi`` (1/s) to pass beside an omega table (None: undamped or not said).
    transition : str
        ``"saddle-node"``, ``"subcritical-pitchfork"``, ``"supercritical-pitchfork"`` or
        ``"none"`` (no loss of stability).
    critical : float or None
        The load the lab must not cross (the fold for imperfect softening, ``P_c`` for a
        perfect column, the snap load of the truss); None when stability is never lost.
    p_c : float or None
        The perfect column's critical load (None for the truss).
    eps : float
        Stress-free angle (rad; 0 = perfect; the first bar's for coupled columns).
    least_stiffness_load, least_omega2 : float or None
        Imperfect stiffening only: where the stiffness along the path is least, and the
        ``omega^2`` there.
    stop : float
        ``d``: the last load is ``P_ref (1 - d)``.
    rel : float
        Relative noise of ``omega^2``.
    omega2_true : ndarray
        The exact ``omega^2`` at ``mu`` (1/s^2).
    q_true : ndarray
        The exact static level at ``mu`` (rad or m).
    model : LinkColumn or VonMisesTruss
    """

    index: int
    kind: str
    family: str
    mu: np.ndarray
    sigma2: np.ndarray | None
    sigma2_std: np.ndarray | None
    omega: np.ndarray | None
    omega_std: np.ndarray | None
    w_static: np.ndarray | None
    w_static_std: np.ndarray | None
    damping: float | None
    transition: str
    critical: float | None
    p_c: float | None
    eps: float
    least_stiffness_load: float | None
    least_omega2: float | None
    stop: float
    rel: float
    omega2_true: np.ndarray = field(repr=False)
    q_true: np.ndarray = field(repr=False)
    model: Any = field(repr=False)

    @property
    def p_ref(self) -> float:
        """The load the stop is measured from (``critical``, else ``p_c``)."""
        return float(self.critical if self.critical is not None else self.p_c)

    def predict_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of the product's ``predict(mu, **kw)`` (columns present)."""
        kw: dict[str, Any] = {}
        for name in ("sigma2", "sigma2_std", "omega", "omega_std", "w_static", "w_static_std"):
            v = getattr(self, name)
            if v is not None:
                kw[name] = v
        if self.damping is not None:
            kw["damping"] = self.damping
        return kw

    def csv_text(self) -> str:
        """The table as a lab's CSV (header ``mu,...``; 17 significant digits)."""
        cols = {"mu": self.mu, **self.predict_kwargs()}
        cols.pop("damping", None)
        names = list(cols)
        rows = [",".join(f"{float(cols[c][i]):.17g}" for c in names) for i in range(self.mu.size)]
        return ",".join(names) + "\n" + "\n".join(rows) + "\n"


def _log_uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def make_model(
    rng: np.random.Generator, kind: str, *, family: str | None = None, eps: float | None = None
) -> tuple[str, LinkColumn | VonMisesTruss]:
    """A random structure of ``kind``: ``(family, model)``.

    Columns: ``P_c`` log-uniform in [20, 500] N (``L`` in [0.5, 2] m), the unloaded
    fundamental 2-20 Hz; softening ones a rotational spring with ``beta`` in [-1.5, -0.3]
    (``kappa`` in [-1.33, -0.13]) or the lateral spring (``kappa = -1/2``), stiffening ones
    ``beta`` in [-0.1, 1] (``kappa`` in [0.07, 1.17]); imperfect ones ``|eps|`` log-uniform in
    [1e-4, 3e-3] rad, its sign random. Truss: rise 0.1-0.35 rad, snap load 20-500 N,
    2-20 Hz; the asymmetric one's second bar 1.05-1.5 times stiffer.
    """
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
    f0 = _log_uniform(rng, 2.0, 20.0)
    w0 = 2.0 * math.pi * f0
    if kind == "truss":
        rise = rng.uniform(0.1, 0.35)
        unit = VonMisesTruss(k=1.0, rise=rise)
        k = _log_uniform(rng, 20.0, 500.0) / unit.snap_load_closed_form()
        stiff0 = VonMisesTruss(k=k, rise=rise).d2V(0.0)
        return "truss", VonMisesTruss(k=k, rise=rise, mass=stiff0 / w0**2)
    if kind == "truss-asymmetric":
        rise, ratio = rng.uniform(0.1, 0.35), rng.uniform(1.05, 1.5)
        unit = AsymmetricTruss(k1=1.0, k2=ratio, rise=rise)
        k = _log_uniform(rng, 20.0, 500.0) / unit.critical_load()
        model = AsymmetricTruss(k1=k, k2=k * ratio, rise=rise)
        stiff0 = float(np.linalg.eigvalsh(model.hessian(0.0, 0.0))[0])
        return "truss-asymmetric", AsymmetricTruss(k1=k, k2=k * ratio, rise=rise,
                                                   mass=stiff0 / w0**2)  # fmt: skip
    if kind.startswith("coupled"):
        return "coupled-columns", _coupled(rng, kind.endswith("softening"), w0)
    imperfect = kind.startswith("imperfect")
    if eps is None:
        sign = 1.0 if rng.random() < 0.5 else -1.0
        eps = sign * _log_uniform(rng, 1e-4, 3e-3) if imperfect else 0.0
    if imperfect and eps == 0.0:
        raise ValueError(f"an imperfect kind needs eps != 0, got eps={eps!r}")
    if not imperfect and eps != 0.0:
        raise ValueError(f"a perfect kind needs eps == 0, got eps={eps!r}")
    softening = kind.endswith("softening")
    if family is None:
        family = "column-lateral" if softening and rng.random() < 0.5 else "column-rotational"
    if family == "column-lateral" and not softening:
        raise ValueError("the lateral-spring column is always softening")
    p_c = _log_uniform(rng, 20.0, 500.0)
    L = rng.uniform(0.5, 2.0)
    if family == "column-lateral":
        k, beta = p_c / L, 0.0
        kr = k * L * L  # the rotational stiffness U''(0) at eps = 0
    elif family == "column-rotational":
        k = p_c * L
        beta = rng.uniform(-1.5, -0.3) if softening else rng.uniform(-0.1, 1.0)
        kr = k
    else:
        raise ValueError(f"family must be column-rotational or column-lateral, got {family!r}")
    spring = family.split("-")[1]
    return family, LinkColumn(spring, k=k, L=L, inertia=kr / w0**2, beta=beta, eps=eps)


def _coupled(rng: np.random.Generator, softening: bool, w0: float) -> CoupledColumns:
    """Two imperfect columns joined at the top: ``k2 / k1`` in [1, 1.5], ``c L^2 / k1`` in
    [0.2, 2], ``beta`` as a single column's, each ``|eps_i|`` log-uniform in [1e-4, 3e-3] with
    a random sign; ``P_c`` log-uniform in [20, 500] N. Drawn again (at most 20 times) until
    the pair folds (softening) or does not (stiffening), and when the path cannot be followed
    on the leading angle (it turns back)."""
    for _ in range(20):
        L = rng.uniform(0.5, 2.0)
        ratio, gam = rng.uniform(1.0, 1.5), rng.uniform(0.2, 2.0)
        beta = rng.uniform(-1.5, -0.3) if softening else rng.uniform(-0.1, 1.0)
        e1, e2 = (
            (1.0 if rng.random() < 0.5 else -1.0) * _log_uniform(rng, 1e-4, 3e-3) for _ in "12"
        )
        unit = CoupledColumns(k1=1.0, k2=ratio, c=gam / L**2, L=L, beta=beta, eps1=e1, eps2=e2)
        k1 = _log_uniform(rng, 20.0, 500.0) / unit.p_c
        m = CoupledColumns(k1=k1, k2=k1 * ratio, c=k1 * gam / L**2, L=L, beta=beta, eps1=e1,
                           eps2=e2)  # fmt: skip
        stiff0 = float(np.linalg.eigvalsh(m.hessian(m._unloaded(), 0.0))[0])
        m = CoupledColumns(k1=m.k1, k2=m.k2, c=m.c, L=L, inertia=stiff0 / w0**2, beta=beta,
                           eps1=e1, eps2=e2)  # fmt: skip
        try:
            folds = m.fold() is not None
            m.omega2(0.9 * (m.critical_load() or m.p_c))  # the path reaches the plan's loads
        except (RuntimeError, ValueError):
            continue  # a pair whose leading angle turns back on the path: drawn again
        if folds == softening:
            return m
    raise RuntimeError("no coupled pair of the kind asked in 20 draws")  # pragma: no cover


def random_plan(
    rng: np.random.Generator,
    kind: str,
    *,
    index: int = 0,
    family: str | None = None,
    eps: float | None = None,
    grid: str | None = None,
    stop: float | None = None,
    n_max: int = 40,
    rel: float | None = None,
    static: bool | None = None,
    input: str = "sigma2",
    damping: float | None = None,
) -> Plan:
    """A random lab plan on a random structure of ``kind`` (see the module docstring).

    Parameters
    ----------
    rng : numpy Generator
    kind : str
        One of :data:`KINDS`.
    index : int
        Number carried in the plan.
    family, eps : optional
        Fix the model family (``"column-rotational"``, ``"column-lateral"``) or the
        imperfection (rad); random when None.
    grid : ``"coarse"``, ``"fine"`` or None (random)
    stop : float, optional
        ``d`` of the last load ``P_ref (1 - d)``; log-uniform in [1e-3, 1e-1] when None.
    n_max : int
        At most this many loads.
    rel : float, optional
        Relative noise of ``omega^2``; log-uniform in [1e-5, 1e-3] when None.
    static : bool, optional
        Hand over the static level (random, half the plans, when None).
    input : str
        One of :data:`INPUTS`.
    damping : float, optional
        ``xi`` (1/s) of the structure: given with an omega table, the rows whose undamped
        ``omega_0 < xi / 2`` carry their slow over-damped rate
        ``xi/2 - sqrt(xi^2/4 - omega_0^2)`` (the table's ``omega`` is otherwise the pole's
        modulus ``omega_0`` whatever the damping).
    """
    if input not in INPUTS:
        raise ValueError(f"input must be one of {INPUTS}, got {input!r}")
    family, model = make_model(rng, kind, family=family, eps=eps)
    if grid is None:
        grid = "coarse" if rng.random() < 0.5 else "fine"
    if grid not in ("coarse", "fine"):
        raise ValueError(f"grid must be 'coarse' or 'fine', got {grid!r}")
    d = _log_uniform(rng, 1e-3, 1e-1) if stop is None else float(stop)
    if not 0 < d < 1:
        raise ValueError(f"stop must be in (0, 1), got {d!r}")
    r = _log_uniform(rng, 1e-5, 1e-3) if rel is None else float(rel)
    static = bool(rng.random() < 0.5) if static is None else static

    critical = model.critical_load()
    p_c = model.p_c if isinstance(model, (LinkColumn, CoupledColumns)) else None
    p_ref = critical if critical is not None else p_c
    assert p_ref is not None
    h_rel = rng.uniform(0.02, 0.1) if grid == "coarse" else rng.uniform(0.004, 0.02)
    last = p_ref * (1.0 - d)
    h = h_rel * p_ref
    n = min(int(math.floor(last / h)) + 1, n_max)
    mu = last - h * np.arange(n)[::-1]
    omega2 = np.array([model.omega2(float(P)) for P in mu])
    q = np.array([model.equilibrium(float(P)) for P in mu])
    if not np.all(omega2 > 0):  # pragma: no cover - every path here is stable
        raise AssertionError("a plan's path must be stable")

    least_load = least_om2 = None
    if isinstance(model, LinkColumn) and model.least_stiffness() is not None:
        _, least_load, k_min = model.least_stiffness()
        least_om2 = k_min / model.inertia
    if isinstance(model, CoupledColumns) and critical is None:
        least_load, k_min = coupled_least_stiffness(model)
        least_om2 = k_min / model.inertia

    sd2 = r * omega2
    sigma2 = -(omega2 + sd2 * rng.standard_normal(n))
    cols: dict[str, np.ndarray | None] = dict.fromkeys(
        ("sigma2", "sigma2_std", "omega", "omega_std", "w_static", "w_static_std")
    )
    xi = None
    if input.startswith("sigma2"):
        cols["sigma2"] = sigma2
        if input == "sigma2":
            cols["sigma2_std"] = sd2
    else:
        om0 = np.sqrt(omega2)
        if damping is not None:
            xi = float(damping)
            over = om0 < xi / 2
            rate = np.where(over, xi / 2 - np.sqrt(np.maximum(xi * xi / 4 - omega2, 0.0)), om0)
        else:
            rate = om0
        om_sd = 0.5 * r * rate
        cols["omega"] = rate + om_sd * rng.standard_normal(n)
        if input == "omega":
            cols["omega_std"] = om_sd
    if static:
        scale = max(float(np.max(np.abs(q))), 1e-3 * (getattr(model, "L", None) or model.L0))
        wsd = np.full(n, r * scale)
        cols["w_static"] = q + wsd * rng.standard_normal(n)
        cols["w_static_std"] = wsd
    return Plan(
        index=index, kind=kind, family=family, mu=mu, damping=xi,
        transition=TRANSITION[kind], critical=critical, p_c=p_c,
        eps=float(getattr(model, "eps", getattr(model, "eps1", 0.0))),
        least_stiffness_load=least_load,
        least_omega2=least_om2, stop=d, rel=r, omega2_true=omega2, q_true=q, model=model,
        **cols,
    )  # fmt: skip


def impulse_record(
    plan: Plan,
    i: int,
    *,
    dt: float,
    n: int,
    damping: float = 0.0,
    noise: float = 1e-3,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    """The impulse response at the plan's load ``mu[i]``: the damped linear oscillator of the
    structure about its equilibrium, ``x'' + xi x' + omega_0^2 x = 0``, ``x(0) = 0``,
    ``x'(0) = 1``, on the static level ``q``, sampled at ``t = j dt``, plus white noise of
    ``noise`` times the response's peak.

    Returns the record ``w`` (rad or m), shape ``(n,)``.
    """
    om2 = float(plan.omega2_true[i])
    xi = float(damping)
    t = dt * np.arange(n)
    disc = xi * xi / 4 - om2
    if disc < 0:
        wd = math.sqrt(-disc)
        x = np.exp(-xi * t / 2) * np.sin(wd * t) / wd
    elif disc > 0:
        s = math.sqrt(disc)
        r1, r2 = -xi / 2 + s, -xi / 2 - s
        x = (np.exp(r1 * t) - np.exp(r2 * t)) / (r1 - r2)
    else:
        x = t * np.exp(-xi * t / 2)
    rng = rng if rng is not None else np.random.default_rng(i)
    peak = float(np.max(np.abs(x)))
    return plan.q_true[i] + x + noise * peak * rng.standard_normal(n)


def records(
    plan: Plan,
    *,
    zeta: float = 0.01,
    noise: float = 1e-3,
    periods: float = 12.0,
    samples_per_period: float = 20.0,
    max_samples: int = 200_000,
    seed: int = 0,
) -> list[tuple[np.ndarray, float, float]]:
    """The plan as a lab's impulse records, ``[(w, dt, load), ...]``.

    One sample step for every record (``samples_per_period`` samples in the fastest period)
    and one length (``periods`` periods of the slowest, at most ``max_samples``); the damping
    ``xi = 2 zeta omega_0`` of the first (least loaded) record, the same at every load (so the
    damping ratio grows as the mode softens).
    """
    om = np.sqrt(plan.omega2_true)
    dt = 2.0 * math.pi / float(om.max()) / samples_per_period
    n = int(min(max_samples, math.ceil(periods * 2.0 * math.pi / float(om.min()) / dt)))
    xi = 2.0 * zeta * float(om[0])
    rng = np.random.default_rng(seed)
    return [
        (impulse_record(plan, i, dt=dt, n=n, damping=xi, noise=noise, rng=rng), dt, float(P))
        for i, P in enumerate(plan.mu)
    ]


def write_records(plan: Plan, folder: Any, **kw: Any) -> Any:
    """:func:`records` (same keywords) written as a lab's files: one CSV ``t,w`` per load and a
    manifest ``path,control`` (the ``snapwarn sweep`` door), returned as the manifest's path.
    """
    from pathlib import Path

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    lines = ["path,control"]
    for i, (w, dt, P) in enumerate(records(plan, **kw)):
        t = dt * np.arange(w.size)
        name = f"rec{i:03d}.csv"
        body = "\n".join(f"{a:.9g},{b:.9g}" for a, b in zip(t, w))
        (folder / name).write_text("t,w\n" + body + "\n")
        lines.append(f"{name},{P!r}")
    manifest = folder / "manifest.csv"
    manifest.write_text("\n".join(lines) + "\n")
    return manifest
