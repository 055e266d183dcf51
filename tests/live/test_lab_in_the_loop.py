"""A lab that follows the advice, over HTTP with the SDK against a real uvicorn.

The structure is not the product's: ``tests/labrec`` (numpy alone) writes the records of a
fundamental that softens as a saddle-node or a pitchfork (sub- or supercritical) in the lab's
units (degrees, seconds, millimetres), with the lab's impairments (the hammer's contact, mains
hum, higher modes, noise; drawn per seed). The lab starts far (0 deg, its step 4 deg, mu* drawn
in 25..60 deg), records where the service advises with the length and step it suggests, and
stops when the service says ``converged``, gives no safe step, or after 30 records. Checked
against the generator's truth:

- no record at or past mu*;
- the last interval covers mu* and is narrower than 1 % of the distance travelled;
- the same with one bad record injected (the hammer missed: noise alone), which is set aside
  by name while the sweep goes on;
- on a clean fixed grid approaching mu*, the alarm's rank never decreases;
- the same ten labs on an imperfect softening pitchfork, judged against its fold (the snap).
"""

from __future__ import annotations

import math
import time

import httpx2
import numpy as np
import pytest
from _lab_loop import BUDGET, KINDS, STEP, Answer, F, L, campaign, follow, imperfect_campaign

from service.client import Client


@pytest.fixture(scope="module")
def ready(server):  # noqa: ANN001, ANN201
    """The server once its analysis workers have loaded their kernels (``/healthz`` ready)."""
    for _ in range(300):
        if httpx2.get(server.url + "/healthz", timeout=10.0).json().get("ready"):
            return server
        time.sleep(1.0)
    raise RuntimeError("the analysis workers never became ready")


def session(
    client: Client, camp: F.Campaign, bad_at: int | None = None, time_unit: str | None = "s"
) -> list:
    """Follow the advice from 0 deg over HTTP (tests/live/_lab_loop.py's lab); the updates.
    The lab's records are in seconds and say so (``time_unit``), as a lab's files do."""
    live = client.live_sweep(f"{camp.kind} seed {camp.seed}", control="theta", unit="deg",
                             step=STEP)  # fmt: skip

    def add(k: int, y: np.ndarray, dt: float, mu: float) -> Answer:
        u = live.add(w=y, dt=dt, control=mu, name=f"rec_{k:02d}.csv", unit=time_unit)
        return Answer(u, u.converged, u.next_control, u.record_duration, u.record_dt)

    answers = follow(camp, add, bad_at)
    live.close()
    return [a.update for a in answers]


def check(camp: F.Campaign, updates: list, bad_at: int | None, width: float = 0.01) -> None:
    """The issue's criteria for one session: covered, narrower than ``width`` (1 %) of the
    distance travelled, within the budget, the bad record set aside by name."""
    controls = [u.control for u in updates]
    assert max(controls) < camp.mu_star
    last = updates[-1]
    lo, hi = last.mu_star_interval
    assert lo <= camp.mu_star <= hi, (camp.kind, camp.seed, lo, hi, camp.mu_star)
    assert hi - lo < width * (max(controls) - controls[0]), (hi - lo, max(controls))
    assert len(updates) <= BUDGET
    if bad_at is not None and bad_at < len(updates):
        names = [a.name for a in last.set_aside]
        assert f"rec_{bad_at:02d}.csv" in names and last.n_set_aside == len(names)


def sessions(server, kinds, seeds, bad_at) -> None:  # noqa: ANN001
    with Client(server.url, timeout=300.0) as c:
        for kind in kinds:
            for seed in seeds:
                camp = campaign(kind, seed)
                check(camp, session(c, camp, bad_at), bad_at)


def test_a_lab_following_the_advice(ready) -> None:  # noqa: ANN001
    """The fast version: one saddle-node session with a missed hammer at the sixth record."""
    sessions(ready, ("saddle-node",), (1,), bad_at=5)


_UNITLESS = [
    ("supercritical-pitchfork", None),
    # record 17 (sampled near 59.9 Hz) shows the 60 Hz hum aliased near 0.1 Hz (sigma2 -1.66,
    # barely damped) beside the line's -33.37: the sweep keeps the line (reconcile's strays);
    # it ended 1.46 % wide on that alias before
    ("subcritical-pitchfork", 6),
]


@pytest.mark.slow
@pytest.mark.parametrize(("kind", "bad_at"), _UNITLESS)
def test_a_lab_whose_records_carry_no_time_unit(ready, kind: str, bad_at) -> None:  # noqa: ANN001
    """Seed 1's labs without a time unit on their records (the advice's rate then meets the
    mains alias): the issue's criteria all the same."""
    with Client(ready.url, timeout=300.0) as c:
        camp = campaign(kind, 1)
        check(camp, session(c, camp, bad_at, time_unit=None), bad_at)


CELLS = [(k, b) for b in (None, 6) for k in KINDS]


@pytest.mark.slow
@pytest.mark.parametrize(("kind", "bad_at"), CELLS)
def test_ten_labs_per_type_following_the_advice(ready, kind: str, bad_at) -> None:  # noqa: ANN001
    """Ten labs per type: none ever records at or past mu* (asserted on every record, inside
    ``follow``); every session ends covered, narrower than 1 % of the distance travelled,
    within 30 records, the bad record set aside by name."""
    misses = []
    with Client(ready.url, timeout=300.0) as c:
        for seed in range(1, 11):
            camp = campaign(kind, seed)
            updates = session(c, camp, bad_at)  # asserts: never at or past mu*
            try:
                check(camp, updates, bad_at)
            except AssertionError as exc:
                misses.append((seed, str(exc)[:160]))
    assert not misses, f"{len(misses)} of 10 sessions miss the issue's criteria: {misses}"


#: Imperfect labs whose sessions end wider than 1 % of the distance travelled. Seeds 6 (2.02 %
#: clean, 1.99 % with the missed hammer) and 7 (1.01 % clean) were, on 98996e3: their last
#: record repeated 10-16 times while the interval reached down to it; since the advice fills
#: in between the last two controls after one such repeat, in process: 0.061 %, 0.073 % and
#: 0.093 % (the 20 imperfect sessions all under 0.39 %, covering the fold, never past it,
#: within 30 records).
_WIDE_IMPERFECT: set[tuple[int | None, int]] = set()


@pytest.mark.slow
@pytest.mark.parametrize("bad_at", [None, 6])
def test_ten_labs_on_an_imperfect_structure(ready, bad_at) -> None:  # noqa: ANN001
    """Ten labs on an imperfect softening pitchfork (tests/live/_lab_loop.py: the cusp, its
    fold 0.5-3 % of the distance before the perfect pitchfork): the fold is the value judged.
    None records at or past the fold; every session ends covering it within 30 records, the
    bad record set aside by name, narrower than 1 % of the distance travelled (2.5 % for the
    sessions of ``_WIDE_IMPERFECT``, which are asserted still wide: a fix shows here)."""
    misses = []
    with Client(ready.url, timeout=300.0) as c:
        for seed in range(1, 11):
            camp = imperfect_campaign(seed)
            updates = session(c, camp, bad_at)  # asserts: never at or past the fold
            controls = [u.control for u in updates]
            lo, hi = updates[-1].mu_star_interval
            travelled = max(controls) - controls[0]
            wide = (bad_at, seed) in _WIDE_IMPERFECT
            try:
                check(camp, updates, bad_at, width=0.025 if wide else 0.01)
                if wide:
                    assert hi - lo > 0.01 * travelled, f"seed {seed} now narrow: update the list"
            except AssertionError as exc:
                misses.append((seed, str(exc)[:160]))
    assert not misses, f"{len(misses)} of 10 sessions miss the issue's criteria: {misses}"


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_the_rank_never_decreases_on_a_clean_approach(ready, kind: str) -> None:  # noqa: ANN001
    """Clean records (no hum, 50 dB noise) on a grid that approaches mu*: the alarm's rank
    after each record never falls."""
    camp = campaign(kind, 3)
    lab = L.Lab(quantity="displacement", fs=2000.0, duration=4.0, pulse_s=10e-3, peak_mm=0.3,
                snr_db=50.0)
    camp = F.Campaign(kind, camp.mu_star, 0.0, f1_hz=12.0, lab=lab, seed=3, ramp=0.0,
                      wobble=0.0, offset=0.0)  # fmt: skip
    ms = camp.mu_star
    grid = [*np.arange(0.0, 0.95 * ms, ms / 10), *(ms * (1 - 0.05 * 0.5 ** np.arange(5)))]
    with Client(ready.url, timeout=300.0) as c:
        live = c.live_sweep(f"clean {kind}", control="theta", unit="deg")
        ranks = []
        for k, mu in enumerate(grid):
            rec = camp.record(float(mu), k)
            ranks.append(live.add(w=rec.y, dt=rec.dt, control=float(mu)).alarm.rank)
        live.close()
    assert ranks == sorted(ranks), ranks
    assert ranks[0] == 0 and ranks[-1] == 4
    assert math.isfinite(ms)
