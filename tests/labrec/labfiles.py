"""Lab files and campaigns from :mod:`labgen` (numpy only; never ``sim`` or ``service``).

Writers (the way labs write records; every one readable by ``service.recordings``):

``csv_iso``        an accelerometer logger: ``time,accel [m/s2]`` with ISO times of day
                   (``14:03:12.000500``);
``npz_ms``         a laser sensor's NPZ: ``t_ms`` and ``w_mm`` (``v_mm_s``, ``a_m_s2`` for the
                   other quantities);
``csv_semicolon``  a European spreadsheet: ``t [s];w [mm]`` with decimal commas;
``csv``            plain ``t [s],w [mm]``.

Campaigns: a structure whose fundamental softens toward ``mu*`` (control in degrees)::

    omega0^2(mu) = omega0^2(mu0) ((mu* - mu) / (mu* - mu0))^e,   e = 1/2 (saddle-node),
                                                                  e = 1 (pitchforks)

with a constant decay rate ``gamma`` (the fundamental becomes overdamped only within
``omega0 < gamma``), stiff higher modes, a hammer of fixed force (the response grows as the
structure softens), and on a displacement sensor the static deflection of the normal form
``w = w_c + s (mu* - mu)^b``, ``b = 1/2`` (saddle-node, supercritical pitchfork) or ``b = 1``
(subcritical pitchfork) (docs/physics.md, "Critical slowing down"). :func:`write_campaign`
writes the files and the manifest ``path,control`` that ``snapwarn sweep`` reads;
:meth:`Campaign.record` gives one record at any control (a lab in the loop).
"""

from __future__ import annotations

import datetime
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from labgen import Lab, LabRecord, Modes, synthesize

KINDS = ("saddle-node", "subcritical-pitchfork", "supercritical-pitchfork")
_EXPONENT = {"saddle-node": 0.5, "subcritical-pitchfork": 1.0, "supercritical-pitchfork": 1.0}
_STATIC_B = {"saddle-node": 0.5, "subcritical-pitchfork": 1.0, "supercritical-pitchfork": 0.5}
STYLES = ("csv_iso", "npz_ms", "csv_semicolon", "csv")
SPURIOUS = ("bad_kick", "heavy_clipping", "no_ringdown")
_LABEL = {"displacement": "w", "velocity": "v", "acceleration": "accel"}
_NPZ = {"displacement": "w_mm", "velocity": "v_mm_s", "acceleration": "a_m_s2"}


def _table(head: str, t: list[str], y: np.ndarray, sep: str, fmt: str) -> str:
    return head + "\n" + "".join(f"{a}{sep}{fmt % b}\n" for a, b in zip(t, y, strict=True))


def write_record(rec: LabRecord, path: Path, style: str, start_s: float = 50592.0) -> Path:
    """Write ``rec`` as a lab would (``style`` one of :data:`STYLES`); ``start_s`` is the time
    of day of the first sample for ``csv_iso`` (default 14:03:12)."""
    unit = rec.unit
    name = f"{_LABEL[rec.quantity]} [{unit}]"
    if style == "npz_ms":
        np.savez(path, t_ms=1e3 * rec.t, **{_NPZ[rec.quantity]: rec.y})
        if path.suffix != ".npz":  # np.savez appends .npz
            Path(str(path) + ".npz").rename(path)
        return path
    if style == "csv_iso":
        day = datetime.datetime(2026, 11, 27) + datetime.timedelta(seconds=start_s)
        times = [(day + datetime.timedelta(seconds=float(x))).strftime("%H:%M:%S.%f")
                 for x in rec.t]  # fmt: skip
        path.write_text(_table(f"time,{name}", times, rec.y, ",", "%.7e"))
    elif style == "csv_semicolon":
        times = [f"{x:.6f}".replace(".", ",") for x in rec.t]
        body = _table(f"t [s];{name}", times, rec.y, ";", "%.7e").replace(".", ",")
        path.write_bytes(body.encode("cp1252"))
    elif style == "csv":
        times = [f"{x:.6f}" for x in rec.t]
        path.write_text(_table(f"t [s],{name}", times, rec.y, ",", "%.7e"))
    else:
        raise ValueError(f"style {style!r} is not one of {STYLES}")
    return path


def suffix(style: str) -> str:
    return ".npz" if style == "npz_ms" else ".csv"


@dataclass(frozen=True)
class RecordTruth:
    """One campaign file: its name, control, the fundamental's truth and what was done to it."""

    name: str
    control: float
    f_hz: float
    omega0: float
    sigma2: float
    gamma: float
    static: float | None
    spurious: str | None = None
    clipped: bool = False
    kicks: int = 1


@dataclass(frozen=True)
class CampaignTruth:
    """What :func:`write_campaign` wrote: the transition, mu*, the manifest and every file."""

    kind: str
    mu_star: float
    manifest: Path
    records: tuple[RecordTruth, ...]

    @property
    def spurious(self) -> dict[str, str]:
        """file name -> why it is spurious."""
        return {r.name: r.spurious for r in self.records if r.spurious}


@dataclass(frozen=True)
class Campaign:
    """A softening structure in a lab (see the module docstring for the laws).

    ``lab`` holds the sensor and the impairments common to every record (quantity, rate,
    pulse, pre-trigger, hum level, SNR); per record, the drift's ramp and wobble, the hum's
    phases and the noise are drawn from ``seed`` and the record's index ``k``; records whose
    index is in ``clip_at`` are clipped (``clip_level``) and those in ``repeat_at`` have a
    second kick."""

    kind: str = "saddle-node"
    mu_star: float = 42.0  # deg
    mu0: float = 0.0
    f1_hz: float = 12.0  # fundamental's undamped frequency at mu0
    gamma: float = 0.3  # fundamental's decay rate, 1/s
    higher: tuple[tuple[float, float, float], ...] = ((41.0, 0.008, 0.7), (97.0, 0.006, -0.5))
    static_c: float = 1.5  # mm, deflection at mu*
    static_s: float = 0.6  # mm per deg^b
    lab: Lab = field(default_factory=Lab)
    cycles: float = 40.0  # fundamental cycles per record (at least base duration)
    offset: float = 0.2  # sensor offset, fraction of the reference peak (campaign-wide)
    ramp: float = 0.03  # per record, up to this fraction of the peak
    wobble: float = 0.02
    clip_at: tuple[int, ...] = ()
    clip_level: float = 0.85
    repeat_at: tuple[int, ...] = ()
    seed: int = 1

    def modes(self, mu: float) -> Modes:
        x = (self.mu_star - mu) / (self.mu_star - self.mu0)
        if x <= 0:
            raise ValueError(f"control {mu} is at or past mu* = {self.mu_star}")
        w0 = 2 * math.pi * self.f1_hz * x ** (_EXPONENT[self.kind] / 2)
        f = [w0 / (2 * math.pi)] + [h[0] for h in self.higher]
        z = [self.gamma / w0] + [h[1] for h in self.higher]
        return Modes(tuple(f), tuple(z), (1.0,) + tuple(h[2] for h in self.higher))

    def static(self, mu: float) -> float:
        return self.static_c + self.static_s * (self.mu_star - mu) ** _STATIC_B[self.kind]

    def gain(self) -> float:
        """The largest displacement of the unit hammer at ``mu0`` (``lab.peak_mm`` over it is the
        fixed hammer's gain)."""
        t = np.arange(int(self.lab.fs * 2 / self.f1_hz) + 1) / self.lab.fs
        lab = replace(self.lab, pretrigger=0.0, duration=float(t[-1]) + 1 / self.lab.fs,
                      hum=0.0, offset=0.0, ramp=0.0, wobble=0.0, snr_db=None, clip=None,
                      kicks=(), static_mm=0.0, quantity="displacement", gain=1.0)  # fmt: skip
        r = synthesize(self.modes(self.mu0), lab, np.random.default_rng(0))
        return float(np.max(np.abs(r.y)))

    def record(self, mu: float, k: int = 0, *, duration: float | None = None,
               dt: float | None = None, spurious: str | None = None) -> LabRecord:  # fmt: skip
        """The record at control ``mu`` (the ``k``-th of the campaign: its random draws), of
        ``duration`` s at step ``dt`` s when given (a lab following advice)."""
        rng = np.random.default_rng([self.seed, k])
        modes = self.modes(mu)
        fs = self.lab.fs if dt is None else 1.0 / dt
        if duration is None:
            duration = max(self.lab.duration, self.cycles / modes.f0_hz[0])
        duration = min(duration, 60000 / fs)
        lab = replace(
            self.lab, fs=fs, duration=duration, gain=self.lab.peak_mm / self.gain(),
            static_mm=self.static(mu), offset=self.offset,
            ramp=float(rng.uniform(-self.ramp, self.ramp)),
            wobble=float(rng.uniform(0, self.wobble)), wobble_hz=float(rng.uniform(0.05, 0.3)),
            clip=self.clip_level if k in self.clip_at else None,
            kicks=((float(rng.uniform(0.45, 0.7)), float(rng.uniform(0.5, 1.0))),)
            if k in self.repeat_at else (),
        )  # fmt: skip
        if spurious is not None:
            modes, lab = _spoil(spurious, modes, lab)
        return synthesize(modes, lab, rng)


def _spoil(what: str, modes: Modes, lab: Lab) -> tuple[Modes, Lab]:
    """A record that must not be trusted: ``bad_kick`` (the hammer hit a node of the
    fundamental: it does not ring, the higher modes do), ``heavy_clipping`` (a sensor range of
    15 % of the record's largest value), ``no_ringdown`` (the trigger fired, no kick landed)."""
    if what == "bad_kick":
        return replace(modes, coef=(0.0,) + modes.coef[1:]), lab
    if what == "heavy_clipping":
        return modes, replace(lab, clip=0.15)
    if what == "no_ringdown":
        return modes, replace(lab, gain=1e-9 * (lab.gain or 1.0), kicks=())
    raise ValueError(f"spurious {what!r} is not one of {SPURIOUS}")


def controls_for(camp: Campaign, n: int = 12, slowdown: float = 3.0) -> np.ndarray:
    """``n`` evenly spaced controls from ``mu0`` to where the period is ``slowdown`` times its
    value at ``mu0`` (``T ~ (mu* - mu)^(-e/2)``)."""
    x_last = slowdown ** (-2.0 / _EXPONENT[camp.kind]) * (camp.mu_star - camp.mu0)
    return np.linspace(camp.mu0, camp.mu_star - x_last, n)


def write_campaign(camp: Campaign, directory: Path, *, controls: np.ndarray | None = None,
                   style: str = "csv_iso", spurious: dict[int, str] | None = None,
                   dt_column: bool = False) -> CampaignTruth:  # fmt: skip
    """Write a campaign's files (``rec_00.csv``...) and ``manifest.csv`` (``path,control`` and
    ``dt`` when ``dt_column``) into ``directory``; ``spurious`` maps a record's index to one of
    :data:`SPURIOUS`. Returns the truth."""
    directory.mkdir(parents=True, exist_ok=True)
    mus = controls_for(camp) if controls is None else np.asarray(controls, dtype=float)
    spurious = spurious or {}
    rows, truths = [], []
    for k, mu in enumerate(mus):
        bad = spurious.get(k)
        rec = camp.record(float(mu), k, spurious=bad)
        name = f"rec_{k:02d}{'_' + bad if bad else ''}{suffix(style)}"
        write_record(rec, directory / name, style, start_s=50592.0 + 60.0 * k)
        tr = rec.truth
        truths.append(RecordTruth(name, float(mu), tr.f_hz, tr.omega0, tr.sigma2, tr.gamma,
                                  tr.static, bad, rec.lab.clip is not None,
                                  len(rec.lab.kicks) + 1))  # fmt: skip
        rows.append(f"{name},{float(mu)!r}" + (f",{rec.dt!r}" if dt_column else ""))
    manifest = directory / "manifest.csv"
    manifest.write_text("path,control" + (",dt" if dt_column else "") + "\n"
                        + "\n".join(rows) + "\n")  # fmt: skip
    return CampaignTruth(camp.kind, camp.mu_star, manifest, tuple(truths))


def issue_campaigns() -> dict[str, tuple[Campaign, str]]:
    """The two campaigns of the issue, every impairment on: a saddle-node at 42 deg read by an
    accelerometer (ISO times of day) and a supercritical pitchfork at 31 deg read by a laser
    displacement sensor (``;`` CSV with decimal commas): 2 kHz, a 15 ms half-sine hammer, a
    10 % pre-trigger, hum at 3 % of the peak with its 3rd harmonic, drift, 25 dB noise, some
    clipped records and some with a second kick. name -> (campaign, file style)."""
    common = {"fs": 2000.0, "duration": 4.0, "pulse_s": 15e-3, "pretrigger": 0.10,
              "hum": 0.03, "harmonics": ((3, 0.4),), "snr_db": 25.0, "peak_mm": 0.3}  # fmt: skip
    sn = Campaign("saddle-node", 42.0, 0.0, f1_hz=12.0,
                  lab=Lab(quantity="acceleration", mains_hz=50.0, **common),
                  clip_at=(3, 9), repeat_at=(5, 12), seed=11)  # fmt: skip
    pf = Campaign("supercritical-pitchfork", 31.0, 0.0, f1_hz=9.0, static_c=0.0, static_s=0.5,
                  higher=((33.0, 0.008, 0.6), (80.0, 0.006, -0.4)),
                  lab=Lab(quantity="displacement", mains_hz=60.0, **common),
                  clip_at=(4,), repeat_at=(2, 8), seed=12)  # fmt: skip
    return {"saddle-node": (sn, "csv_iso"), "supercritical-pitchfork": (pf, "csv_semicolon")}
