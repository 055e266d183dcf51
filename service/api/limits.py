"""Bounds checked at the door, before any work: simulation cost, queue length per owner.

Each failing check is a problem naming the field, the value and the setting that bounds it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from service.api.problems import ApiProblem, as_problems, invalid
from service.api.settings import Settings
from service.api.storage import Store

#: Backends whose cost grows with the number of elements: the Cosserat rod (time steps x
#: elements). The Euler beam (a fixed Galerkin basis) and the normal form ignore ``elements``:
#: their cost is bounded by the duration and the samples.
DISCRETISED = ("cosserat",)


@dataclass(frozen=True)
class Plan:
    """What a scene will run: the backend (``model="auto"`` resolved) and, for the rod, the
    elements it will use, the request field that set them (``elements`` or ``rtol``) and its
    time grid (``cost``: a ``sim.resolution.RodCost``; None where it is not known)."""

    model: str
    elements: int | None = None
    field: str = "elements"
    rtol: float | None = None
    cost: Any = None

    @property
    def steps(self) -> int | None:
        """The rod's time steps (None: not known)."""
        return None if self.cost is None else int(self.cost.steps)


def check_simulation(
    scene: dict[str, Any], model: str | None, settings: Settings, plan: Plan | None = None
) -> None:
    """422 when a scene would cost more than the settings allow.

    Bounds: ``elements <= max_elements``, ``duration <= max_sim_duration``, ``duration / dt <=
    max_samples`` and, for the rod (``plan.model`` in DISCRETISED), ``elements x time steps <=
    max_sim_work`` with what it will run (``plan``, see :func:`plan_scene`: the elements given
    or chosen from ``rtol``, and the steps of ``sim.resolution.rod_cost``: the duration given
    or the default 40 fundamental periods, at ~rtol^-1/2 steps per period, or one per sample
    where dt is finer). Without a plan (the cheap checks before any numerics) the budget is
    checked only where the request itself names the rod, its elements, duration and dt: one
    step per sample at least.
    """
    elements = scene.get("elements")
    if elements is not None and elements > settings.max_elements:
        raise invalid(
            "elements",
            elements,
            f"exceeds the limit of {settings.max_elements} (setting SNAPWARN_MAX_ELEMENTS)",
        )
    if plan is None and model in DISCRETISED and elements is not None:
        plan = Plan(model, int(elements))
    duration = scene.get("duration")
    dt = scene.get("dt")
    if duration is not None:
        if not math.isfinite(duration) or duration > settings.max_sim_duration:
            raise invalid(
                "duration",
                duration,
                f"exceeds the limit of {settings.max_sim_duration:g} time units "
                "(setting SNAPWARN_MAX_SIM_DURATION)",
            )
        if dt is not None and dt > 0 and duration / dt > settings.max_samples:
            raise invalid(
                "dt",
                dt,
                f"gives {duration / dt:.3g} samples over duration={duration:g}, more than "
                f"{settings.max_samples} (setting SNAPWARN_MAX_SAMPLES)",
            )
    if plan is not None and plan.model in DISCRETISED and plan.elements is not None:
        _check_work(scene, plan, settings)


def _check_work(scene: dict[str, Any], plan: Plan, settings: Settings) -> None:
    """422 when the rod's elements x time steps exceed ``max_sim_work``, naming the field
    that drives the steps: ``dt`` where the sampling is finer than the rod's own step, ``rtol``
    where it is below the default and the default's steps would fit, else ``duration`` (the
    default when none is given)."""
    from sim.resolution import rod_time_grid
    from sim.scene import DEFAULT_RTOL

    duration, dt = scene.get("duration"), scene.get("dt")
    rtol = scene.get("rtol")
    rtol = DEFAULT_RTOL if rtol is None else float(rtol)
    cost, budget = plan.cost, settings.max_sim_work
    if cost is None:  # before the numerics (or no equilibrium to run from): one step a sample
        if duration is None or dt is None or not dt > 0:
            return
        steps = math.floor(duration / dt + 1e-9)
    else:
        steps = int(cost.steps)
    work = plan.elements * steps
    if work <= budget:
        return
    how = "" if plan.field == "elements" else f" (chosen from rtol={plan.rtol:g})"
    charge = (
        f"x elements={plan.elements}{how} = {work:.3g} element-steps, more than the "
        f"budget {budget:.3g} of the {plan.model} backend (setting SNAPWARN_MAX_SIM_WORK)"
    )
    if cost is None:
        raise invalid(
            "dt",
            dt,
            f"gives at least {steps} time steps (one per sample) over "
            f"duration={duration:g} {charge}",
        )
    g, period = cost.grid, cost.period
    per = f"at least {g.steps_per_period} steps per fundamental period ({period:.3g})"
    over = f"{steps} time steps over duration={g.duration:.3g}"
    if dt is not None and g.every == 1 and g.sample_dt < period / g.steps_per_period:
        raise invalid(
            "dt",
            dt,
            f"is finer than the rod's own step ({per} for rtol={rtol:g}): "
            f"{over} {charge}; ask for a larger dt",
        )
    if rtol < DEFAULT_RTOL:
        base = rod_time_grid(period, DEFAULT_RTOL, duration, dt)
        if plan.elements * base.steps <= budget:
            raise invalid(
                "rtol",
                rtol,
                f"asks for {per}: {over} {charge}; the default "
                f"rtol={DEFAULT_RTOL:g} ({base.steps} steps) fits",
            )
    fits = math.floor(budget / plan.elements / g.every) * g.sample_dt
    what = (
        ""
        if duration is not None
        else f"(the default: {g.duration / period:g} fundamental periods of {period:.3g}) "
    )
    raise invalid(
        "duration",
        duration,
        f"{what}gives {steps} time steps ({per} for "
        f"rtol={rtol:g}) {charge}; ask for duration <= {fits:.3g}",
    )


def plan_scene(scene: dict[str, Any], model: str, *, timed: bool = True) -> Plan:
    """Validate ``scene`` with ``sim.Scene`` (422 naming the field) and find what it will run:
    the backend ``model="auto"`` picks (``sim.select.choose_model``) and, for the rod, its
    elements (``sim.resolution``: the elements given, or those chosen from ``rtol``; an rtol
    beyond the policy's cap is a 422 naming rtol) and its time steps
    (``sim.resolution.rod_cost``: the grid the simulation will run about the scene's
    equilibrium; ``timed=False``: not looked for, a route whose steps are its own).
    Blocking (numerics, cached per strip and equilibrium): call it in a thread."""
    import sim

    try:
        with as_problems("scene"):
            s = sim.Scene(**scene)
            backend = model
            if model == "auto":
                from sim.select import choose_model

                backend = choose_model(s).model
            if backend not in DISCRETISED:
                return Plan(backend)
            from sim.backends import BACKENDS
            from sim.resolution import rod_cost

            res = BACKENDS[backend].resolution(s)
            cost = rod_cost(s, int(res.size)) if timed else None
    except TypeError as exc:  # a field the scene does not have
        raise ApiProblem(422, str(exc), field="scene", value=sorted(scene)) from None
    given = s.elements is not None
    return Plan(backend, int(res.size), "elements" if given else "rtol",
                None if given else float(s.rtol), cost)  # fmt: skip


def check_scene(
    scene: dict[str, Any], model: str, settings: Settings, *, timed: bool = True
) -> Plan:
    """Everything a scene is checked for at the door of every route that runs one
    (``POST /v1/simulations``, ``POST /v1/snaps``): the settings' bounds, the scene's own
    rules and the budget of the backend that will run it with the elements it will use.
    ``timed=False``: a route that runs its own fixed number of steps (a snap: 4000, so its
    cost is bounded by the elements' limit), whose scene's ``duration`` is not a simulation's
    and is not charged. Blocking (see :func:`plan_scene`): call it in a thread. Returns the
    plan."""
    check_simulation(scene, model, settings)  # the cheap bounds first: no numerics for them
    try:
        plan = plan_scene(scene, model, timed=timed)
    except ApiProblem as exc:  # an rtol beyond the resolution policy's own cap
        if scene.get("elements") is not None or [e.get("field") for e in exc.errors] != ["rtol"]:
            raise
        plan = Plan("cosserat", None, "rtol", scene.get("rtol"))
    if plan.field == "rtol" and (plan.elements is None or plan.elements > settings.max_elements):
        need = (
            f"needs {plan.elements} elements of the rod, more than"
            if plan.elements
            else "needs more elements of the rod than"
        )
        raise invalid(
            "rtol",
            plan.rtol,
            (
                f"{need} the limit of {settings.max_elements} (setting SNAPWARN_MAX_ELEMENTS)"
                + _rtol_hint(scene, settings.max_elements)
                + " or give elements"
            ),
        )
    if timed:
        check_simulation(scene, model, settings, plan)
    return plan


def _rtol_hint(scene: dict[str, Any], elements: int) -> str:
    """``: ask for rtol >= X`` where X is the accuracy the rod reaches at ``elements`` (the
    resolution policy's estimate), or a plainer hint where there is none."""
    from sim.resolution import rod_error_constant, rod_resolution
    from sim.scene import Scene

    try:
        s = Scene(**scene)
        strip = {"end_shortening": s.end_shortening, "slenderness": s.slenderness,
                 "poisson": s.poisson}  # fmt: skip
        err = rod_resolution(s.actuation, elements=elements, **strip).mu_star_error
        mu = rod_error_constant(s.actuation, s.end_shortening, s.slenderness, s.poisson)[1]
        x = 2.0 * err / abs(mu)
        step = 10.0 ** (math.floor(math.log10(x)) - 1)  # two digits, rounded up: enough
        return f": ask for rtol >= {math.ceil(x / step) * step:.2g}"
    except Exception:  # noqa: BLE001 - only a hint
        return ": ask for a larger rtol"


def check_queue(store: Store, owner: str, settings: Settings) -> None:
    """429 when ``owner`` already has ``max_active_jobs_per_owner`` queued or running jobs (a
    quick answer before any work; the bound itself is held by the store, which counts and
    queues in one locked transaction: ``max_active`` of ``Store.create_job``)."""
    n = store.count_active_jobs(owner)
    if n >= settings.max_active_jobs_per_owner:
        raise queue_full(n, settings.max_active_jobs_per_owner)


def queue_full(n: int, limit: int) -> ApiProblem:
    """The 429 of an owner whose queue is full."""
    return ApiProblem(
        429,
        f"{n} jobs of this owner are queued or running, the limit is {limit} (setting "
        "SNAPWARN_MAX_ACTIVE_JOBS_PER_OWNER); retry when some have finished, or cancel some",
        title="Too many jobs",
        slug="too-many-jobs",
        field="jobs",
        value=n,
        headers={"Retry-After": "10"},
    )


#: Bounds of a time axis: the step and every time stay where their squares and inverses are
#: finite (the numerics form 1/dt and omega^2 ~ 1/dt^2).
DT_MIN, DT_MAX, T_ABS_MAX = 1e-100, 1e100, 1e100


def check_time_axis(n: int, dt: float, t0: float, t: Any = None, field: str = "dt") -> None:
    """422 unless ``n >= 2``, ``DT_MIN <= dt <= DT_MAX`` and every time is within
    ``T_ABS_MAX`` (so the duration, the rates and the stored values are finite)."""
    if n < 2:
        raise invalid("w", n, "needs at least 2 samples (one sample has no duration)")
    if not (math.isfinite(dt) and DT_MIN <= dt <= DT_MAX):
        raise invalid(field, dt, f"must lie in [{DT_MIN:g}, {DT_MAX:g}]")
    end = t0 + dt * (n - 1)
    if not (math.isfinite(end) and abs(t0) <= T_ABS_MAX and abs(end) <= T_ABS_MAX):
        raise invalid(
            "t0" if abs(t0) > T_ABS_MAX else field,
            t0 if abs(t0) > T_ABS_MAX else dt,
            f"puts the time axis (t0={t0:g} to {end:g}) beyond +-{T_ABS_MAX:g}",
        )
    if t is not None:
        import numpy as np

        if np.size(t) and float(np.max(np.abs(t))) > T_ABS_MAX:
            raise invalid("t", float(np.max(np.abs(t))), f"has times beyond +-{T_ABS_MAX:g}")


def check_depth(obj: Any, field: str, max_depth: int) -> None:
    """422 when ``obj`` (parsed JSON) nests deeper than ``max_depth`` (checked iteratively)."""
    stack = [(obj, 1)]
    while stack:
        x, d = stack.pop()
        if isinstance(x, (dict, list)):
            if d > max_depth:
                raise invalid(field, f"<nested {d} deep>", f"nests deeper than {max_depth} levels")
            stack.extend((v, d + 1) for v in (x.values() if isinstance(x, dict) else x))


def check_finite_json(obj: Any, field: str) -> None:
    """422 naming the first non-finite number in ``obj`` (parsed JSON; ``metadata.a[2].b``):
    ``NaN`` and ``Infinity`` are not JSON numbers, whichever way the body was parsed."""
    stack = [(obj, field)]
    while stack:
        x, where = stack.pop()
        if isinstance(x, float) and not math.isfinite(x):
            raise invalid(where, x, "must be finite (NaN and Infinity are not numbers of JSON)")
        if isinstance(x, dict):
            stack.extend((v, f"{where}.{k}") for k, v in reversed(list(x.items())))
        elif isinstance(x, list):
            stack.extend((v, f"{where}[{i}]") for i, v in reversed(list(enumerate(x))))


def loads_bounded(text: str, field: str, max_depth: int) -> Any:
    """``json.loads`` that refuses nesting beyond ``max_depth`` before parsing (no recursion)."""
    import json

    depth = deepest = 0
    in_str = esc = False
    for ch in text:  # metadata fields are small (form fields); a linear scan is cheap
        if in_str:
            if esc:
                esc = False
            elif ch == "\\":
                esc = True
            elif ch == '"':
                in_str = False
        elif ch == '"':
            in_str = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
            if deepest > max_depth:
                raise invalid(
                    field,
                    f"<nested over {max_depth} deep>",
                    f"nests deeper than {max_depth} levels",
                )
        elif ch in "]}":
            depth -= 1
    try:
        return json.loads(text)
    except (json.JSONDecodeError, RecursionError) as exc:
        raise invalid(field, text, f"is not JSON ({getattr(exc, 'msg', exc)})") from None


def check_json_samples(body: bytes, max_samples: int, extra: int = 100_000) -> None:
    """413 before parsing when a JSON body holds more numbers than ``w`` and ``t`` may have
    (counted as commas: a C scan of the bytes, no parsing)."""
    if len(body) > 2 * max_samples + extra:  # else it cannot hold too many commas
        check_value_count(body.count(b","), max_samples, extra)


def check_value_count(commas: int, max_samples: int, extra: int = 100_000) -> None:
    """413 when ``commas`` (counted in a JSON body, or in its part read so far) exceed what
    ``w`` and ``t`` of ``max_samples`` samples each, plus ``extra`` other values, need."""
    if commas > 2 * max_samples + extra:
        from service.api.problems import too_large

        raise too_large(
            "w",
            f"~{commas} values",
            f"the body holds about {commas} values, more than 2 x {max_samples} samples "
            "(setting SNAPWARN_MAX_SAMPLES)",
        )
