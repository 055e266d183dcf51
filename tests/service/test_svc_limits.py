"""Bounded work: job time limits (the job's process is stopped), cancellation, no re-run after
restarts, a queue bound per owner, budgets checked at the door, progress that moves."""

from __future__ import annotations

import asyncio
import time
from collections.abc import AsyncIterator
from datetime import timedelta

import httpx2
import pytest
from _svc_helpers import test_settings

from service.api import create_app
from service.api.storage import Store, utcnow

pytestmark = pytest.mark.anyio


@pytest.fixture(scope="module")
async def runner_app(tmp_path_factory) -> AsyncIterator[tuple[object, httpx2.AsyncClient]]:  # noqa: ANN001
    """An app whose job runner runs each job in its own process (two at a time)."""
    db = tmp_path_factory.mktemp("limits") / "l.db"
    app = create_app(
        test_settings(
            f"sqlite:///{db}", job_workers=2, warm_pool=False, max_active_jobs_per_owner=3
        )
    )
    async with app.router.lifespan_context(app):
        transport = httpx2.ASGITransport(app=app)
        async with httpx2.AsyncClient(transport=transport, base_url="http://127.0.0.1") as c:
            yield app, c


async def _until(client, job_id: str, statuses: tuple[str, ...], timeout: float = 60) -> dict:  # noqa: ANN001
    end = time.monotonic() + timeout
    while True:
        doc = (await client.get(f"/v1/jobs/{job_id}")).json()
        if doc["status"] in statuses:
            return doc
        assert time.monotonic() < end, doc
        await asyncio.sleep(0.05)


async def test_a_job_past_its_time_limit_is_stopped(runner_app) -> None:  # noqa: ANN001
    """A job that never reports progress is still stopped: its process is killed."""
    app, c = runner_app
    store: Store = app.state.snapwarn.store
    job = store.create_job(
        "diagnostic-sleep", {"seconds": 60, "steps": 1}, time_limit_s=1.5, owner="local"
    )
    app.state.snapwarn.runner.wake()
    t0 = time.monotonic()
    doc = await _until(c, job.id, ("failed", "succeeded"), timeout=60)
    assert doc["status"] == "failed" and doc["error"]["reason"] == "time-limit", doc
    assert "1.5 s" in doc["error"]["detail"]
    assert time.monotonic() - t0 < 30
    await asyncio.sleep(1.0)  # nothing runs it again
    assert store.get_job(job.id).status == "failed"
    assert not app.state.snapwarn.runner._running


async def test_cancel_stops_a_running_job(runner_app) -> None:  # noqa: ANN001
    app, c = runner_app
    store: Store = app.state.snapwarn.store
    job = store.create_job("diagnostic-sleep", {"seconds": 60, "steps": 1}, time_limit_s=120)
    app.state.snapwarn.runner.wake()
    await _until(c, job.id, ("running",))
    r = await c.post(f"/v1/jobs/{job.id}/cancel")
    assert r.status_code == 200 and r.json()["status"] == "cancelled"
    end = time.monotonic() + 20
    while job.id in app.state.snapwarn.runner._running:  # its process is stopped
        assert time.monotonic() < end
        await asyncio.sleep(0.05)
    assert (await c.post(f"/v1/jobs/{job.id}/cancel")).json()["status"] == "cancelled"
    done = store.create_job("diagnostic-sleep", {"seconds": 0})
    app.state.snapwarn.runner.wake()
    await _until(c, done.id, ("succeeded",))
    r = await c.post(f"/v1/jobs/{done.id}/cancel")
    assert r.status_code == 409 and r.json()["errors"][0]["field"] == "status"


async def test_a_stopped_job_leaves_no_process_behind(runner_app) -> None:  # noqa: ANN001
    """A job's own processes (an atlas's dask scheduler and workers) stop with it: cancelled,
    its child was left running (parent pid 1) when only the job's process was killed."""
    import os

    app, c = runner_app
    store: Store = app.state.snapwarn.store
    job = store.create_job("diagnostic-sleep", {"seconds": 60, "steps": 1, "child": True},
                           time_limit_s=120)  # fmt: skip
    app.state.snapwarn.runner.wake()
    end = time.monotonic() + 60
    while not (
        msg := (await c.get(f"/v1/jobs/{job.id}")).json()["progress"]["message"] or ""
    ).startswith("child"):
        assert time.monotonic() < end
        await asyncio.sleep(0.05)
    pid = int(msg.split()[-1])
    os.kill(pid, 0)  # alive
    assert (await c.post(f"/v1/jobs/{job.id}/cancel")).status_code == 200
    end = time.monotonic() + 20
    while True:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            break
        assert time.monotonic() < end, "the job's child process outlived it"
        await asyncio.sleep(0.05)


async def test_progress_moves_with_the_work(runner_app) -> None:  # noqa: ANN001
    app, c = runner_app
    store: Store = app.state.snapwarn.store
    job = store.create_job("diagnostic-sleep", {"seconds": 3, "steps": 6}, time_limit_s=60)
    app.state.snapwarn.runner.wake()
    seen = set()
    end = time.monotonic() + 60
    while (doc := (await c.get(f"/v1/jobs/{job.id}")).json())["status"] != "succeeded":
        seen.add(round(doc["progress"]["fraction"], 3))
        assert time.monotonic() < end
        await asyncio.sleep(0.05)
    assert len({f for f in seen if 0 < f < 1}) >= 3, seen


async def test_queue_bound_per_owner(runner_app) -> None:  # noqa: ANN001
    app, c = runner_app
    store: Store = app.state.snapwarn.store
    mine = [store.create_job("diagnostic-sleep", {"seconds": 30, "steps": 30}, owner="q")
            for _ in range(3)]  # fmt: skip
    from service.api import limits
    from service.api.problems import ApiProblem

    with pytest.raises(ApiProblem) as err:
        limits.check_queue(store, "q", app.state.snapwarn.settings)
    assert err.value.status == 429 and err.value.headers["Retry-After"]
    limits.check_queue(store, "someone-else", app.state.snapwarn.settings)
    for j in mine:
        store.cancel_job(j.id, "test over")
    limits.check_queue(store, "q", app.state.snapwarn.settings)


async def test_budgets_are_checked_at_the_door(runner_app) -> None:  # noqa: ANN001
    _, c = runner_app
    cases = [
        ({"model": "cosserat", "duration": 1e5}, "duration"),
        ({"model": "cosserat", "duration": 400, "elements": 200}, "duration"),
        ({"elements": 10_000_000}, "elements"),
        ({"elements": 1000}, "elements"),
        ({"model": "normal-form", "duration": 10, "dt": 1e-9}, "dt"),
        # the rod's time steps are charged: a tiny rtol (steps per period ~ rtol^-1/2) ...
        ({"model": "cosserat", "mu": 0.5, "duration": 1.0, "elements": 40, "rtol": 1e-9}, "rtol"),
        # ... and the default duration (40 periods) when none is given
        ({"model": "cosserat", "mu": 0.5, "elements": 400, "rtol": 1e-6}, "rtol"),
    ]
    for doc, field in cases:
        # Refused before any work: the in-process server's CPU time stays far below what one of
        # these runs would cost (minutes to hours); the wall clock only bounds a run elsewhere,
        # generously, since a loaded machine stretches it (09:09 at load 18: 7.6 s for a 422).
        t0, c0 = time.perf_counter(), time.process_time()
        r = await c.post("/v1/simulations", json=doc)
        assert r.status_code == 422, (doc, r.text)
        assert r.json()["errors"][0]["field"] == field, (doc, r.json())
        assert time.process_time() - c0 < 2.0
        assert time.perf_counter() - t0 < 60.0


def _refused(scene: dict, settings: object, model: str = "cosserat") -> dict:
    """The one error of the 422 ``check_scene`` raises (field, value, message)."""
    from service.api import limits
    from service.api.problems import ApiProblem

    with pytest.raises(ApiProblem) as err:
        limits.check_scene(scene, model, settings)
    assert err.value.status == 422, err.value.detail
    assert "SNAPWARN_MAX_SIM_WORK" in err.value.detail, err.value.detail
    return err.value.errors[0]


def test_a_rod_run_without_duration_is_charged_its_default_duration() -> None:
    """No duration: the rod runs 40 fundamental periods (sim.cosserat.dynamics.simulate),
    12 000 steps at the default rtol; they are charged as a given duration's would be."""
    from service.api import Settings, limits

    small = Settings(max_sim_work=1e6)
    scene = {"mu": 0.5, "elements": 100}  # 100 x 12 000 = 1.2e6 element-steps
    err = _refused(scene, small)
    assert err["field"] == "duration" and err["value"] is None, err
    assert "default" in err["message"] and "elements=100" in err["message"], err
    plan = limits.check_scene(scene, "cosserat", Settings(max_sim_work=1.2e6))  # just fits
    assert plan.steps == 12_000 and plan.elements * plan.steps == 1_200_000
    limits.check_scene({**scene, "duration": 2.0}, "cosserat", small)  # ~390 steps/unit time


def test_a_snap_is_not_charged_as_a_simulation() -> None:
    """A snap runs its own 4000 steps (sim.snap), whatever the scene's rtol or duration: the
    door that refuses the same scene as a 40-period simulation over the budget lets it pass
    as a snap, rtol far below the default included (the rod's elements are what bound it)."""
    from service.api import Settings, limits

    small = Settings(max_sim_work=1e6)
    scene = {"mu": 0.5, "elements": 100}
    assert _refused(scene, small)["field"] == "duration"
    plan = limits.check_scene(scene, "cosserat", small, timed=False)
    assert plan.elements == 100 and plan.steps is None
    limits.check_scene({**scene, "rtol": 1e-9}, "cosserat", small, timed=False)


@pytest.mark.parametrize("rtol", [5e-324, 1e-320, 1e-310, 1e-300])
@pytest.mark.parametrize("timed", [True, False])
def test_a_subnormal_rtol_is_a_422_on_rtol(rtol: float, timed: bool) -> None:
    """Found by the fuzz pass: an rtol of 5e-324 made (rtol / 2) mu* underflow to 0 in the
    rod's resolution policy, a ZeroDivisionError and a 500 at POST /v1/snaps. Every tiny
    rtol is refused on its own field, as a simulation (timed) and as a snap (untimed)."""
    from service.api import Settings, limits
    from service.api.problems import ApiProblem

    for model in ("cosserat", "auto"):
        with pytest.raises(ApiProblem) as err:
            limits.check_scene({"mu": 0.5, "rtol": rtol}, model, Settings(), timed=timed)
        assert err.value.status == 422, err.value.detail
        assert [e["field"] for e in err.value.errors] == ["rtol"], err.value.errors
        assert err.value.errors[0]["value"] == rtol


@pytest.mark.parametrize("actuation", ["asymmetric", "symmetric", "antisymmetric"])
@pytest.mark.parametrize(
    "mu",  # the rod's continuation to |mu| = 1000 takes 2-8 s: slow
    [pytest.param(m, marks=pytest.mark.slow) for m in (-1e3, 1e3)] + [5e-324, -5e-324, 1e-100],
)
def test_extreme_mu_at_the_door_is_a_plan_or_a_422(actuation: str, mu: float) -> None:
    """Found by a scan of the wire's bounds: mu = 5e-324 divided by zero in the beam's statics
    (the model choice at 'auto'); mu = -1000 indexed past a list in the rod's near-fold
    fallback. The door answers every bound with a plan or a 422, never an exception."""
    from service.api import Settings, limits
    from service.api.problems import ApiProblem

    for model in ("auto", "cosserat"):
        try:
            limits.check_scene({"mu": mu, "actuation": actuation}, model, Settings())
        except ApiProblem as exc:
            assert exc.status == 422, exc.detail


def test_a_tiny_rtol_is_charged_for_its_time_steps() -> None:
    """Steps per period grow as rtol^-1/2 (the time-stepping error (omega dt)^2 / 12 <= rtol/4),
    whatever the elements: 40 elements over 1 time unit at rtol=1e-9 is ~7.5e5 steps."""
    from service.api import Settings, limits

    settings = Settings()
    scene = {"mu": 0.5, "duration": 1.0, "elements": 40}
    fine = limits.check_scene(scene, "cosserat", settings)
    err = _refused({**scene, "rtol": 1e-9}, settings)
    assert err["field"] == "rtol" and err["value"] == 1e-9, err
    assert err["message"].startswith("rtol: 1e-09 asks for at least 114715 steps per"), err
    tiny = limits.plan_scene({**scene, "rtol": 1e-9}, "cosserat")
    assert tiny.elements == fine.elements == 40 and tiny.steps > 300 * fine.steps


def test_a_sampling_step_finer_than_the_rods_is_charged_at_once() -> None:
    """dt below the rod's own step sets the steps (one per sample): refused from the request
    alone (no numerics), naming dt."""
    from service.api import Settings, limits
    from service.api.problems import ApiProblem

    scene = {"mu": 0.5, "duration": 400.0, "dt": 1e-4, "elements": 400}  # 4e6 x 400
    with pytest.raises(ApiProblem) as err:
        limits.check_simulation(scene, "cosserat", Settings())
    assert err.value.errors[0]["field"] == "dt" and "SNAPWARN_MAX_SIM_WORK" in err.value.detail


@pytest.mark.parametrize(
    "scene",
    [
        {"mu": 0.5, "elements": 16, "duration": 0.5},
        {"mu": 0.5, "elements": 16},  # the default duration and sampling
        {"mu": 0.5, "elements": 16, "duration": 0.3, "dt": 1e-4},  # dt sets the step
        {"mu": 0.5, "elements": 16, "dt": 0.011},  # the default duration, a given dt
        {"mu": 1.0, "elements": 20, "duration": 0.4, "rtol": 1e-5},
        {"mu": 0.5, "branch": "U_B", "elements": 16, "duration": 0.2, "rtol": 3e-3},
        {"mu": 0.3, "actuation": "symmetric", "duration": 0.2, "rtol": 5e-3},  # elements: rtol
    ],
)
def test_the_charge_is_what_the_rod_runs(scene: dict) -> None:
    """The door's elements x steps are the run's own (``info["steps"]``, ``elements``)."""
    import sim
    from service.api import limits

    plan = limits.plan_scene(scene, "cosserat")
    out = sim.simulate(sim.Scene(**scene), model="cosserat")
    assert out.info["stop"] == "done"
    assert (plan.elements, plan.steps) == (out.info["elements"], out.info["steps"]), scene


def test_restarts_do_not_rerun_limited_or_cancelled_jobs(tmp_path) -> None:  # noqa: ANN001
    store = Store(f"sqlite:///{tmp_path / 'r.db'}")
    store.migrate()
    over = store.create_job("diagnostic-sleep", {}, time_limit_s=5)
    fine = store.create_job("diagnostic-sleep", {}, time_limit_s=500)
    gone = store.create_job("diagnostic-sleep", {})
    for _ in range(3):
        store.claim_job("nohost:1:dead")  # runners on another host, then silent
    store.cancel_job(gone.id, "by the test")
    with store.session() as s:
        from service.api.storage import JobRow

        for jid in (over.id, fine.id):
            row = s.get(JobRow, jid)
            row.attempt_started_at = utcnow() - timedelta(seconds=20)  # ran 11 s
            row.heartbeat_at = utcnow() - timedelta(seconds=9)
    done = dict(store.recover_jobs(lease_s=3, max_attempts=5))
    assert done == {over.id: "failed", fine.id: "queued"}, done
    assert store.get_job(over.id).error["reason"] == "time-limit"
    assert store.get_job(gone.id).status == "cancelled"
    assert store.get_job(fine.id).run_s == pytest.approx(11, abs=0.5)  # counted for next time
    assert store.recover_jobs(lease_s=3, max_attempts=5) == []
    store.dispose()


def test_job_errors_show_a_reason_never_a_traceback(caplog) -> None:  # noqa: ANN001
    from service.analysis.errors import ParameterError
    from service.api.jobs import _problem_dict

    try:
        raise RuntimeError("disk /srv/secret/path.py broke")
    except RuntimeError as exc:
        with caplog.at_level("ERROR", logger="snapwarn.jobs"):
            doc = _problem_dict(exc, "job1")
    assert doc["reason"] == "internal-error" and len(doc["correlation_id"]) == 12
    text = str(doc)
    assert "/srv/" not in text and "Traceback" not in text and "secret" not in text
    assert doc["correlation_id"] in caplog.text and "/srv/secret" in caplog.text  # the log has it
    bad = _problem_dict(ParameterError("damping", -1.0, "damping must be >= 0"), "job2")
    assert bad["status"] == 422 and bad["reason"] == "invalid-input"
    assert bad["errors"][0]["field"] == "damping" and bad["errors"][0]["value"] == -1.0
