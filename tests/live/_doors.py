"""One set of lab records for the doors tests: a lab that follows the advice and goes on
recording after the sweep says ``converged``, with a missed hammer and a record cut short.

The records come from tests/live/_lab_loop.py's lab (the independent generator of
tests/labrec). The lab follows the live sweep in process from 0 deg; record ``bad_at`` is a
missed hammer (noise alone), record ``short_at`` a recorder that stopped after 10 samples (the
detector refuses it). After the first ``converged`` it keeps recording ``extra`` records where
the sweep advises (at the last control when no step is safe): the stretch where a door that
carried its own state could part from a batch of the same records.

The records are written as CSV files (``t [s],w``, every number as Python writes it, so the
samples read back exactly), named ``rec_<k>_theta_<control>.csv`` (``snapwarn watch`` reads
the control in the name); every door reads those files.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from _lab_loop import MAX_DURATION, MIN_DT, STEP, campaign, missed_hammer

#: The record that is cut short (the detector needs at least 16 samples).
SHORT_SAMPLES = 10


@dataclass(frozen=True)
class LabRecord:
    name: str
    control: float
    y: np.ndarray
    dt: float


def session(kind: str, seed: int, *, bad_at: int = 6, short_at: int = 4, extra: int = 3,
            budget: int = 30) -> tuple[list[LabRecord], float]:  # fmt: skip
    """The records in arrival order (increasing control) and the generator's mu*."""
    from service.analysis import live

    camp = campaign(kind, seed)
    plan = live.LivePlan(step=STEP)
    recs: list = []
    out: list[LabRecord] = []
    mu, duration, dt, after = 0.0, None, None, None
    for k in range(budget):
        assert mu < camp.mu_star
        rec = camp.record(mu, k, duration=duration, dt=dt)
        y = rec.y
        if k == bad_at:
            y = missed_hammer(rec, k)
        elif k == short_at:
            y = y[:SHORT_SAMPLES]
        out.append(LabRecord(f"rec_{k:02d}_theta_{float(mu)!r}.csv", float(mu),
                             np.asarray(y, dtype=float), float(rec.dt)))  # fmt: skip
        u = live.update(recs, y, dt=rec.dt, control=mu, plan=plan, name=out[-1].name)
        recs.append(u.record)
        if after is None and u.converged:
            after = k
        if after is not None and k - after >= extra:
            break
        nxt = u.next_control
        mu = float(nxt) if math.isfinite(nxt) and nxt > mu else mu
        if math.isfinite(u.record_duration) and math.isfinite(u.record_dt):
            duration, dt = min(u.record_duration, MAX_DURATION), max(u.record_dt, MIN_DT)
        else:
            duration, dt = None, None
    return out, camp.mu_star


def write(records: list[LabRecord], folder: Path) -> Path:
    """Each record as ``<name>`` (CSV, seconds) and ``manifest.csv`` (path, control)."""
    folder.mkdir(parents=True, exist_ok=True)
    for r in records:
        t = np.arange(r.y.size) * r.dt
        body = "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, r.y, strict=True))
        (folder / r.name).write_text("t [s],w\n" + body)
    manifest = folder / "manifest.csv"
    manifest.write_text("path,control\n" + "".join(f"{r.name},{r.control!r}\n"
                                                    for r in records))  # fmt: skip
    return manifest
