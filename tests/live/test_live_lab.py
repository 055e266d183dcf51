"""A lab loop through the SDK against a real uvicorn: the "strip" is the Euler-beam simulator.

Start at mu = 0, always measure at the next safe control value the service returns, with the
record length and step it suggests, and stop when it says the trusted interval is narrow enough.
The answer must reach the accuracy of ``snapwarn warn`` (|mu* error| <= 1e-5, here measured
1e-7 .. 2e-7) against the beam's own bifurcation (an independent computation: the equilibrium
branches of the statics, not the dynamics), and no measurement may reach mu*.
"""

from __future__ import annotations

import math

import pytest
from _lab import Lab

from service.client import Client
from sim.euler_beam import bifurcation

pytestmark = pytest.mark.slow


def run_lab(client: Client, actuation: str, budget: int = 30) -> tuple[list, list]:
    lab = Lab(actuation)
    live = client.live_sweep(f"lab {actuation}", control="mu", step=0.2)
    mu, duration, dt = 0.0, None, None
    updates = []
    for _ in range(budget):
        w, step = lab.record(mu, duration, dt)
        u = live.add(w=w, dt=step, control=mu)
        updates.append(u)
        if lab.omega0 is None:
            lab.omega0 = u.measurement.omega
        if u.converged or u.next_control is None:
            break
        mu, duration, dt = u.next_control, u.record_duration, u.record_dt
    closed = live.close()
    return updates, [closed]


@pytest.mark.parametrize("actuation", ["asymmetric", "symmetric", "antisymmetric"])
def test_lab_loop_reaches_warn_accuracy(server, actuation: str) -> None:  # noqa: ANN001
    truth = bifurcation(actuation)
    with Client(server.url, timeout=300.0) as c:
        updates, (closed,) = run_lab(c, actuation)
    last = updates[-1]
    assert last.converged, f"stopped after {len(updates)} records without converging"
    assert abs(last.mu_star - truth.mu_star) <= 1e-5
    lo, hi = last.mu_star_interval
    assert lo <= truth.mu_star <= hi
    assert last.transition == truth.transition
    controls = [u.control for u in updates]
    assert max(controls) < truth.mu_star  # never at or past mu*
    assert controls == sorted(controls) and not any(u.record_flags for u in updates)
    for u in updates:  # every advised value stayed below the bound it respected
        if u.next_control is not None and u.next_bound is not None:
            assert u.next_control < u.next_bound
    assert closed.status == "succeeded"
    assert closed.result.prediction.mu_star == pytest.approx(last.mu_star, abs=1e-12)
    print(f"{actuation}: {len(updates)} records, mu* error {last.mu_star - truth.mu_star:.2e}, "
          f"max control {max(controls):.8f} < mu* {truth.mu_star:.8f}")
    assert math.isfinite(last.mu_star)
