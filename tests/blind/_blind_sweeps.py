"""Blind campaigns: a structure, how a lab records it, and how a lab sweeps its control.

numpy and scipy only (never ``sim`` or ``service``). A :class:`Campaign` is one lab's sweep of
one structure: controls chosen the way labs choose them (uneven steps, a repeated control, a
sweep that stops far from the transition, a sweep that goes past it and records the structure
on its other branch), written as CSV files with a ``path,control`` manifest. Its
:class:`Truth` holds ``mu*`` (closed form or Brent to 1e-14) in the control's unit, the kind,
which types a product may name, and the records that cannot be trusted.

Families (:data:`FAMILIES`) and the answer they allow (``right`` names the transition,
``withheld`` honestly does not; anything else is a wrong type):

=================  ==========================================  =============================
family             structure                                   right type
=================  ==========================================  =============================
arch_fold          low shallow arch (kappa e^2 in 20-36)       saddle-node
arch_pitchfork     high arch (kappa e^2 in 66-100)             subcritical-pitchfork
arch_crossing      arch with kappa e^2 in 46-56: the critical  subcritical-pitchfork
                   mode is not the lowest line far from mu*
arch_imperfect     high arch with an asymmetric imperfection   saddle-node or
                   (a fold below P_b)                          subcritical-pitchfork
foundation         column on a Winkler foundation, beta in     pitchfork (static level 0:
                   5-14: mode 2 buckles, mode 1 is the lowest  sub/super cannot be told)
                   line far from mu*
threelink          three-link column (two interacting modes)   pitchfork (static level 0)
truss_friction     two-bar (von Mises) truss with Coulomb      saddle-node
                   friction in its joints (amplitude-
                   dependent damping; ``_blind_truss``)
=================  ==========================================  =============================

``undetermined`` is an honest withholding everywhere, ``pitchfork`` where the truth is one.

Plans: ``lab`` (to ``T/T0`` 3-6), ``far`` (stops at ``T/T0 < 2``: the type must be withheld,
``right`` is empty), ``past`` (``lab`` plus one record beyond mu*: on the snapped branch for an
arch or the truss, growing for a column), ``veryfar`` (even load steps that stop at ``T/T0 = 1.3``,
6-8 controls: the type must be withheld).
"""

from __future__ import annotations

import ast
import math
import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from _blind_recorder import Recording, record, write_csv
from _blind_structures import Arch, FoundationColumn, ThreeLinkColumn, _brent
from _blind_truss import FrictionTruss, record_friction

FAMILIES = ("arch_fold", "arch_pitchfork", "arch_crossing", "arch_imperfect", "foundation",
            "threelink", "truss_friction")  # fmt: skip
PLANS = ("lab", "far", "past", "veryfar")
#: plans that stop far from mu*, where no type may be named (their ``right`` is empty)
FAR_PLANS = ("far", "veryfar")
RIGHT = {
    "arch_fold": {"saddle-node"},
    "arch_pitchfork": {"subcritical-pitchfork"},
    "arch_crossing": {"subcritical-pitchfork"},
    "arch_imperfect": {"saddle-node", "subcritical-pitchfork"},
    "foundation": {"pitchfork"},
    "threelink": {"pitchfork"},
    "truss_friction": {"saddle-node"},
}
WITHHELD = {"undetermined", "pitchfork"}


@dataclass(frozen=True)
class Truth:
    family: str
    plan: str
    mu_star: float  # in the control's unit
    kind: str
    right: frozenset
    withheld: frozenset
    controls: tuple[float, ...]
    names: tuple[str, ...]
    untrusted: dict = field(default_factory=dict)  # file name -> why it cannot be trusted
    t_ratio_last: float = float("nan")  # T/T0 of the critical mode at the last stable record
    control_unit: str = "N"
    manifest: Path | None = None
    params: dict = field(default_factory=dict)
    #: each record's critical mode: undamped sigma^2 = -omega0^2 (1/s^2; > 0 when growing)
    sigma2: tuple[float, ...] = ()
    gamma: float = float("nan")  # every mode's decay rate, 1/s
    static_mm: tuple[float, ...] = ()  # each record's static level at the sensor (mm)

    def write_table(self, path: Path, rel_std: float = 1e-3, seed: int = 0,
                    static: bool = True) -> Path:  # fmt: skip
        """The exact measurements of the stable records (``mu, sigma2, sigma2_std[, w_static,
        w_static_std]``) with Gaussian noise of ``rel_std`` (relative; the static level's std
        is ``rel_std`` of its range): the predictor alone on this structure's laws."""
        rng = np.random.default_rng(seed)
        keep = sorted((i for i, n in enumerate(self.names) if n not in self.untrusted),
                      key=lambda i: self.controls[i])  # fmt: skip
        s2 = np.array([self.sigma2[i] for i in keep])
        sd = rel_std * np.abs(s2)
        ws = np.array([self.static_mm[i] for i in keep])
        wsd = rel_std * max(float(np.ptp(ws)), 1e-6 * max(1.0, float(np.max(np.abs(ws)))))
        with open(path, "w") as fh:
            fh.write("mu,sigma2,sigma2_std" + (",w_static,w_static_std" if static else "") + "\n")
            for j, i in enumerate(keep):
                row = [self.controls[i], s2[j] + sd[j] * rng.standard_normal(), sd[j]]
                if static:
                    row += [ws[j] + wsd * rng.standard_normal(), wsd]
                fh.write(",".join(repr(float(x)) for x in row) + "\n")
        return Path(path)


@dataclass(frozen=True)
class Campaign:
    """One lab's sweep of one structure (see the module docstring)."""

    family: str
    structure: object
    load_scale: float  # control unit per non-dimensional load
    f0_hz: float  # the critical mode's frequency at the first control
    zeta0: float  # the critical mode's damping ratio at the first control
    rec: Recording
    controls: tuple[float, ...]  # non-dimensional loads, in recording order
    past: tuple[float, ...] = ()  # loads recorded beyond mu* (remote branch / growing)
    adaptive_length: bool = True
    max_samples: int = 60000  # the logger's buffer: a record is never longer
    static_mm_per_unit: float = 1.0
    control_unit: str = "N"
    plan: str = "lab"
    spoil: dict = field(default_factory=dict)  # index -> Recording overrides (bad records)
    params: dict = field(default_factory=dict)
    #: joint friction (``_blind_truss``): the cycles the first record rings before the apex
    #: sticks (viscous damping aside); None: no friction, the hammer of ``_blind_recorder``
    friction_cycles: float | None = None

    # -- the structure ----------------------------------------------------------------------
    def state(self, p: float, remote: bool = False):  # noqa: ANN201
        if remote:
            return self.structure.state(p, remote=True)
        return self.structure.state(p)

    def mu_star(self) -> float:
        return float(self.structure.critical_load())

    def omega_scale(self) -> float:
        s0 = self.state(self.controls[0])
        return 2 * math.pi * self.f0_hz / math.sqrt(float(s0.omega2[s0.critical]))

    def gamma(self) -> float:
        return self.zeta0 * 2 * math.pi * self.f0_hz

    def t_ratio(self, p: float) -> float:
        s0, s = self.state(self.controls[0]), self.state(p)
        return math.sqrt(float(s0.omega2[s0.critical]) / float(s.omega2[s.critical]))

    # -- recording ----------------------------------------------------------------------------
    def _duration(self, p: float, remote: bool) -> float:
        if not self.adaptive_length:
            return min(self.rec.duration_s, self.max_samples / self.rec.rate_hz)
        s = self.state(p, remote)
        om2 = float(s.omega2[s.critical]) * self.omega_scale() ** 2
        if om2 <= 0:
            return self.rec.duration_s
        g = self.gamma()
        # 40 periods of the critical mode, or 8 slow decay times when overdamped
        if om2 > g * g:
            d = 40 * 2 * math.pi / math.sqrt(om2 - g * g)
        else:
            d = 8.0 / (g - math.sqrt(g * g - om2))
        d = float(np.clip(d, self.rec.duration_s, 6 * self.rec.duration_s))
        return min(d, self.max_samples / self.rec.rate_hz)

    def force(self) -> float:
        """The hammer's force (fixed for the campaign): the first record peaks at
        ``rec.peak_mm`` on a noiseless laser."""
        quiet = replace(self.rec, sensor="laser", unit="mm", snr_db=None, hum_rel=0.0, rig=None,
                        adc_bits=None, nan_gaps=0, offset=0.0, start="pretrigger", second_hit=None,
                        highpass_hz=None)
        s = self.state(self.controls[0])
        s = replace(s, static=0.0)
        r = record(s, self.omega_scale(), self.gamma(), quiet, 1.0)
        return self.rec.peak_mm / float(np.max(np.abs(r.y)))

    def write(self, folder: Path) -> Truth:
        """Write the records and ``manifest.csv`` into ``folder``; the campaign's truth."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        force, oms, gam = self.force(), self.omega_scale(), self.gamma()
        rows, names, untrusted, sig2, stat = [], [], {}, [], []
        adc_range = None
        items = [(p, False) for p in self.controls] + [(p, True) for p in self.past]
        for i, (p, beyond) in enumerate(items):
            remote = beyond and _snaps(self.structure)
            rec = replace(self.rec, seed=self.rec.seed * 1000 + i,
                          duration_s=self._duration(p, remote))  # fmt: skip
            if i in self.spoil:
                rec = replace(rec, **self.spoil[i])
            st = self.state(p, remote)
            sig2.append(-float(st.omega2[st.critical]) * oms**2)
            stat.append(st.static * self.static_mm_per_unit)
            if self.friction_cycles is not None:
                r = self._friction_record(st, rec, adc_range)
            else:
                r = record(st, oms, gam, rec, force, self.static_mm_per_unit,
                           adc_range=adc_range)  # fmt: skip
            if rec.adc_bits is not None and adc_range is None:
                # the lab sets the range on the first record, with headroom, and keeps it
                adc_range = 2.0 * float(np.nanmax(np.abs(r.y)))
                if self.friction_cycles is not None:
                    r = self._friction_record(st, rec, adc_range)
                else:
                    r = record(st, oms, gam, rec, force, self.static_mm_per_unit,
                               adc_range=adc_range)  # fmt: skip
            c = float(p * self.load_scale)
            name = f"rec{i:02d}_{c:.4g}{self.control_unit}.csv".replace(" ", "")
            write_csv(r, folder / name)
            rows.append((name, c))
            names.append(name)
            if beyond:
                untrusted[name] = "remote branch" if remote else "growing (past mu*)"
            elif i in self.spoil:
                untrusted[name] = ",".join(sorted(self.spoil[i]))
        with open(folder / "manifest.csv", "w") as fh:
            fh.write("path,control\n")
            for name, c in rows:
                fh.write(f"{name},{c!r}\n")
        kind = self.structure.kind()
        far = self.plan in FAR_PLANS
        return Truth(self.family, self.plan, self.mu_star() * self.load_scale, kind,
                     frozenset() if far else frozenset(RIGHT[self.family]),
                     frozenset(WITHHELD), tuple(c for _, c in rows), tuple(names), untrusted,
                     self.t_ratio(max(self.controls)), self.control_unit, folder / "manifest.csv",
                     dict(self.params), tuple(sig2), gam, tuple(stat))  # fmt: skip


    def friction(self) -> tuple[float, float]:
        """``(v0, f)``: the kick's velocity (mm/s: the first record peaks near ``rec.peak_mm``)
        and the joints' Coulomb friction (mm/s^2: ``friction_cycles`` cycles to sticking at the
        first record, viscous damping aside: each cycle loses ``4 f / omega0^2``)."""
        s0 = self.state(self.controls[0])
        w0 = math.sqrt(float(s0.omega2[s0.critical])) * self.omega_scale()
        v0 = self.rec.peak_mm * w0
        return v0, v0 * w0 / (4.0 * float(self.friction_cycles))

    def _friction_record(self, st, rec: Recording, adc_range: float | None):  # noqa: ANN001, ANN202
        v0, f = self.friction()
        return record_friction(st, self.omega_scale(), self.gamma(), rec, v0, f,
                               self.static_mm_per_unit, adc_range=adc_range)  # fmt: skip


def _snaps(structure: object) -> bool:
    """Whether the structure snaps to a remote branch past mu* (else it collapses: grows)."""
    return isinstance(structure, (Arch, FrictionTruss))


# ------------------------------------------------------------------------------------------
# Plans: where a lab records
# ------------------------------------------------------------------------------------------


def control_at_ratio(camp: Campaign, ratio: float) -> float:
    """The load where the critical mode's period is ``ratio`` times the first record's."""
    mu_star = camp.mu_star()
    hi = mu_star - 1e-10 * max(1.0, abs(mu_star))
    return _brent(lambda p: camp.t_ratio(p) - ratio, camp.controls[0], hi)


def lab_controls(camp: Campaign, rng: np.random.Generator, n: int, ratio: float,
                 repeats: int = 1) -> tuple[float, ...]:  # fmt: skip
    """``n`` controls from the first one to ``T/T0 = ratio``: distances to mu* geometric with a
    30 % jitter (uneven steps), the far half evenly spaced in the control, and ``repeats``
    controls recorded twice (not adjacent in time)."""
    mu0, mu_star = camp.controls[0], camp.mu_star()
    end = control_at_ratio(camp, ratio)
    d0, d1 = mu_star - mu0, mu_star - end
    dist = np.geomspace(d0, d1, n)
    jit = np.exp(0.3 * rng.standard_normal(n))
    jit[0] = jit[-1] = 1.0
    dist = np.clip(dist * jit, d1, d0)
    mus = np.unique(np.round(mu_star - dist, 12))
    mus = list(mus)
    for _ in range(repeats):
        j = int(rng.integers(1, len(mus) - 1))
        mus.insert(j + 2 if j + 2 < len(mus) else len(mus), mus[j])
    return tuple(float(m) for m in mus)


def stepped_controls(camp: Campaign, rng: np.random.Generator, n: int, ratio: float,
                     ) -> tuple[float, ...]:  # fmt: skip
    """``n`` controls stepped evenly (each step jittered by up to 20 %) from the first one to
    ``T/T0 = ratio``, one of them recorded twice: a lab that steps its load uniformly."""
    mu0, end = camp.controls[0], control_at_ratio(camp, ratio)
    mus = np.linspace(mu0, end, n)
    step = (end - mu0) / (n - 1)
    mus[1:-1] += 0.2 * step * rng.uniform(-1.0, 1.0, n - 2)
    mus = [float(m) for m in np.round(mus, 12)]
    j = int(rng.integers(1, n - 1))
    mus.insert(min(j + 2, n), mus[j])
    return tuple(mus)


def past_control(camp: Campaign, last: float) -> float:
    """A load beyond mu*: for an arch, half the last gap beyond the transition (the structure
    has snapped); for a column, where the collapse grows by ~e^6 over a record."""
    mu_star = camp.mu_star()
    if _snaps(camp.structure):
        return mu_star + max(0.5 * (mu_star - last), 0.01 * mu_star)
    oms = camp.omega_scale()
    target = -((6.0 / (oms * camp.rec.duration_s)) ** 2)

    def f(p: float) -> float:
        s = camp.state(p)
        return float(np.min(s.omega2)) - target

    return _brent(f, mu_star, 2 * mu_star + 1.0)


# ------------------------------------------------------------------------------------------
# Families
# ------------------------------------------------------------------------------------------


def _structure(family: str, rng: np.random.Generator) -> tuple[object, dict]:
    if family == "arch_fold":
        ke2 = rng.uniform(20.0, 36.0)
        return Arch(e=math.sqrt(ke2)), {"kappa_e2": ke2}
    if family == "arch_pitchfork":
        ke2 = rng.uniform(66.0, 100.0)
        return Arch(e=math.sqrt(ke2)), {"kappa_e2": ke2}
    if family == "arch_crossing":
        ke2 = rng.uniform(46.0, 56.0)
        return Arch(e=math.sqrt(ke2)), {"kappa_e2": ke2}
    if family == "arch_imperfect":
        ke2 = rng.uniform(66.0, 100.0)
        e2 = float(np.exp(rng.uniform(math.log(0.01), math.log(0.2)))) * rng.choice([-1, 1])
        return Arch(e=math.sqrt(ke2), e2=e2), {"kappa_e2": ke2, "e2": e2}
    if family == "foundation":
        beta = rng.uniform(5.0, 14.0)
        return FoundationColumn(beta=beta), {"beta": beta}
    if family == "threelink":
        k2 = rng.uniform(0.6, 1.6)
        m2 = rng.uniform(0.5, 2.0)
        return ThreeLinkColumn(k2=k2, m2=m2), {"k2": k2, "m2": m2}
    if family == "truss_friction":
        h0 = rng.uniform(0.1, 0.3)
        return FrictionTruss(h0=h0, ea=1e4), {"h0": h0}
    raise ValueError(family)


#: each family's lab: how it records (drawn around these)
_LAB = {
    "arch_fold": dict(rate_hz=500.0, sensor="laser", unit="in", hum_rel=0.03,
                      tau_decay_s=4e-3),
    "arch_pitchfork": dict(rate_hz=2000.0, sensor="laser", unit="mm", adc_bits=12),
    "arch_crossing": dict(rate_hz=1000.0, sensor="laser", unit="mm", hum_rel=0.02),
    "arch_imperfect": dict(rate_hz=5000.0, sensor="laser", unit="in"),
    "foundation": dict(rate_hz=20000.0, sensor="geophone", unit="in/s", duration_s=2.0),
    "threelink": dict(rate_hz=1000.0, sensor="laser", unit="deg", start="midring"),
    "truss_friction": dict(rate_hz=2000.0, sensor="laser", unit="mm"),
}  # fmt: skip


def campaign(family: str, plan: str = "lab", seed: int = 0, *, damping: float | None = None,
             friction_cycles: float | None = None,
             **rec_overrides) -> Campaign:  # noqa: ANN003  # fmt: skip
    """A random campaign of ``family`` under ``plan`` (module docstring), reproducible from
    ``seed``; ``damping`` fixes the critical mode's first damping ratio (else 0.005-0.03),
    ``friction_cycles`` the truss's joint friction (else 15-40 cycles to sticking),
    ``rec_overrides`` override the lab's recording."""
    rng = np.random.default_rng([zlib.crc32(family.encode()), PLANS.index(plan), seed])
    structure, params = _structure(family, rng)
    f0 = float(np.exp(rng.uniform(math.log(4.0), math.log(15.0))))
    zeta = damping if damping is not None else float(np.exp(rng.uniform(math.log(0.005),
                                                                         math.log(0.03))))
    lab = dict(_LAB[family])
    lab.update(rec_overrides)
    lab.setdefault("duration_s", 3.0)
    lab.setdefault("snr_db", float(rng.uniform(25.0, 45.0)))
    rec = Recording(seed=seed, **lab)
    mu_star = structure.critical_load()
    load_scale = float(rng.choice([1.0, 10.0, 0.25, 40.0]))
    unit = {1.0: "N", 10.0: "N", 0.25: "kN", 40.0: "lbf"}[load_scale]
    params = params | {"f0_hz": f0, "zeta0": zeta}
    base = Campaign(family, structure, load_scale, f0, zeta, rec, (0.0,),
                    control_unit=unit, plan=plan, params=params)  # fmt: skip
    if plan == "veryfar":
        ratio, n = 1.3, int(rng.integers(6, 9))
    elif plan == "far":
        ratio, n = 1.6, int(rng.integers(7, 9))
    else:
        ratio, n = float(rng.uniform(3.0, 6.0)), int(rng.integers(10, 15))
    if plan == "veryfar":
        controls = stepped_controls(base, rng, n, ratio)
    else:
        controls = lab_controls(base, rng, n, ratio, repeats=1)
    past = (past_control(base, controls[-1]),) if plan == "past" else ()
    params = base.params | {"ratio": ratio, "mu_star_nondim": mu_star}
    friction = None
    if family == "truss_friction":
        # drawn last: the other families' draws are unchanged
        friction = float(rng.uniform(15.0, 40.0)) if friction_cycles is None else friction_cycles
        params = params | {"friction_cycles": friction}
    return replace(base, controls=controls, past=past, params=params, friction_cycles=friction)


def _main(argv: list[str]) -> None:
    """``python tests/blind/_blind_sweeps.py FAMILY PLAN SEED DIR [key=value ...]``: write one
    campaign (``key=value`` override the lab's recording, e.g. ``hum_rel=0.0``) and print its
    truth."""
    family, plan, seed, folder = argv[0], argv[1], int(argv[2]), Path(argv[3])
    over = {k: ast.literal_eval(v) for k, v in (a.split("=", 1) for a in argv[4:])}
    camp = campaign(family, plan, seed, **over)
    truth = camp.write(folder)
    truth.write_table(folder / "table.csv")
    print(f"{family}/{plan}/{seed}: {truth.kind} mu* = {truth.mu_star!r} {truth.control_unit}; "
          f"T/T0 at the last stable record {truth.t_ratio_last:.3f}; {truth.params}")
    for n, c, s2 in zip(truth.names, truth.controls, truth.sigma2, strict=True):
        print(f"  {n}: control {c!r}, critical sigma2 {s2:.6g} 1/s^2"
              + (f" ({truth.untrusted[n]})" if n in truth.untrusted else ""))


if __name__ == "__main__":
    import sys

    _main(sys.argv[1:])
