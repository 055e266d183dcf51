"""Simulator commands: bifurcation, equilibria, spectrum, normal-form, simulate, snap.

Every command takes ``--model`` (the backends of ``sim.backends.BACKENDS``) and one resolution
(``--rtol`` or ``--elements``), so that the commands of one scene agree; a scene without an
answer (past a fold, an unstable equilibrium) is a one-line error (exit 2) naming mu and mu*.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

from service.cli._common import add_json_flag, add_plot_flag, bad, emit, finite
from service.cli._vocab import ACTUATIONS, BRANCHES, MODELS, STATIC_MODELS


def _add_actuation(p: argparse.ArgumentParser) -> None:
    p.add_argument("--actuation", required=True, choices=ACTUATIONS, help="end rotation mode")


def _add_strip(p: argparse.ArgumentParser, *, models: tuple[str, ...], default: str) -> None:
    """--model, the strip (dL/L, h/L, b/L, nu) and the resolution (--rtol or --elements)."""
    p.add_argument("--model", default=default, choices=models)
    p.add_argument("--end-shortening", type=finite, default=None, help="dL/L")
    p.add_argument("--slenderness", type=finite, default=None, help="thickness h/L")
    p.add_argument("--width", type=finite, default=None, help="width b/L (>= h/L)")
    p.add_argument("--poisson", type=finite, default=None, help="Poisson ratio in [0, 0.5]")
    p.add_argument("--rtol", type=finite, default=None,
                   help="requested relative accuracy of mu* and sigma^2 (picks the resolution "
                        "and, for --model auto, the backend)")
    p.add_argument("--elements", type=int, default=None,
                   help="Cosserat elements (even); default: chosen from --rtol")


def _scene(args: argparse.Namespace, **fields):
    from sim.scene import Scene

    for name in ("end_shortening", "slenderness", "width", "poisson", "rtol", "elements"):
        if getattr(args, name, None) is not None:
            fields[name] = getattr(args, name)
    return Scene(actuation=args.actuation, **fields)


def _backend(model: str):
    from sim.backends import BACKENDS

    return BACKENDS[model]


def _resolution_text(res: dict | None) -> str:
    if not res:
        return ""
    return (f"  resolution: {res['model']} size {res['size']}, estimated mu* error "
            f"{res['mu_star_error']:.2g} ({res['method']})")


def _bifurcation(args: argparse.Namespace) -> int:
    from service import convert

    scene = _scene(args)
    doc = convert.bifurcation(_backend(args.model).bifurcation(scene)).model_dump(mode="json")
    lines = [f"{doc['actuation']}: {doc['transition']} at mu* = {doc['mu_star']:.12f} "
             f"({doc['model']})"]
    lines += [
        f"  secondary {s['transition']} at mu* = {s['mu_star']:.12f}" for s in doc["secondary"]
    ]
    lines.append(_resolution_text(doc["resolution"]))
    emit(doc, json_mode=args.json, text="\n".join(lines))
    return 0


def _equilibria(args: argparse.Namespace) -> int:
    from service import convert

    scene = _scene(args, mu=args.mu)
    eqs = _backend(args.model).equilibria(scene)
    doc = convert.equilibria(eqs, actuation=args.actuation, mu=args.mu,
                             model=args.model).model_dump(mode="json")  # fmt: skip
    res = doc["resolution"]
    rows = [f"{'branch':6} {'Lambda':>10} {'W(1/2)':>10} {'W(1/4)':>10} {'energy':>10} stable"]
    rows += [
        f"{e['branch']:6} {e['lambda']:10.6f} {e['w_half']:10.6f} {e['w_quarter']:10.6f} "
        f"{e['energy'] if e['energy'] is not None else float('nan'):10.4f} {e['stable']}"
        for e in doc["equilibria"]
    ]
    rows.append(_resolution_text(res))
    if args.plot:
        from service.charts.cli import plot_equilibria

        plot_equilibria(args.plot, args.actuation, args.mu)
    emit(doc, json_mode=args.json, text="\n".join(rows))
    return 0


def _spectrum(args: argparse.Namespace) -> int:
    if not 1 <= args.modes <= 30:
        raise bad("--modes", args.modes, "must be between 1 and 30")
    from service import convert

    scene = _scene(args, mu=args.mu, branch=args.branch)
    doc = convert.spectrum(_backend(args.model).spectrum(scene, args.modes)).model_dump(mode="json")
    rows = [f"{args.branch} at mu = {args.mu} ({doc['model']}): sigma^2 (omega)"]
    rows += [f"  {s:16.6f}  ({w:.6f})" for s, w in zip(doc["sigma2"], doc["omega"])]
    rows.append(_resolution_text(doc["resolution"]))
    if args.plot:
        from service.charts.cli import plot_spectrum

        plot_spectrum(args.plot, doc, actuation=args.actuation, mu=args.mu, branch=args.branch)
    emit(doc, json_mode=args.json, text="\n".join(rows))
    return 0


def _normal_form(args: argparse.Namespace) -> int:
    from service import convert
    from sim.normal_form import normal_form

    doc = convert.normal_form(normal_form(args.actuation)).model_dump(mode="json")
    emit(doc, json_mode=args.json, text=f"{doc['transition']}: {doc['coefficients']}")
    return 0


def _write_csv(path: str, columns: dict) -> Path:
    out = Path(path)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        with out.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(list(columns))
            for row in zip(*columns.values()):
                w.writerow([repr(float(v)) for v in row])
    except OSError as exc:
        raise bad("--out", path, f"cannot be written: {exc.strerror}") from None
    return out


def _simulate(args: argparse.Namespace) -> int:
    from service import convert
    from sim import simulate

    scene = _scene(args, mu=args.mu, branch=args.branch, damping=args.damping, kick=args.kick,
                   duration=args.duration, dt=args.dt, snr_db=args.snr, seed=args.seed)
    sig = simulate(scene, args.model)
    out = _write_csv(args.out, {"t": sig.t, "w": sig.w})
    doc = convert.simulation(sig, path=str(out)).model_dump(mode="json")
    text = f"wrote {doc['samples']} samples to {out} ({sig.model})"
    if doc["auto"] is not None:
        text += f"\n  auto: {doc['auto']['reason']}"
    elif doc["error"]:
        text += f"\n  estimated relative error {doc['error']['total']:.1e}"
    text += "\n" + _resolution_text(doc["resolution"])
    emit(doc, json_mode=args.json, text=text)
    return 0


def _snap(args: argparse.Namespace) -> int:
    from service import convert
    from sim.snap import snap

    scene = _scene(args, damping=args.damping)
    r = snap(scene, args.model, args.dmu, duration=args.duration)
    path = None
    if args.out:
        path = str(_write_csv(args.out, {"t": r.t, "amplitude": r.amplitude}))
    doc = convert.snap(r, path=path).model_dump(mode="json")
    text = (f"{r.actuation} ({r.model}): from {r.from_branch} at mu = {r.mu:.8g} "
            f"(mu* {'+' if r.mu > r.mu_star else '-'} {r.dmu:.3g}) to {r.to_branch}: snap time "
            + (f"{r.snap_time:.6g}" if r.snap_time is not None else "not reached"))
    if args.plot:
        from service.charts.cli import plot_snap

        plot_snap(args.plot, r)
    emit(doc, json_mode=args.json, text=text)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add the simulator sub-commands to ``sub``."""
    static = STATIC_MODELS
    p = sub.add_parser("bifurcation", help="mu* and type of the transition")
    _add_actuation(p)
    _add_strip(p, models=static, default="euler-beam")
    add_json_flag(p)
    p.set_defaults(func=_bifurcation)

    p = sub.add_parser("equilibria", help="every equilibrium at mu (beam: six branches)")
    _add_actuation(p)
    p.add_argument("--mu", type=finite, required=True)
    _add_strip(p, models=static, default="euler-beam")
    add_json_flag(p)
    add_plot_flag(p, "the Euler beam's branch diagram W(1/2) vs mu (paper's Fig. 1 D-F)")
    p.set_defaults(func=_equilibria)

    p = sub.add_parser("spectrum", help="sigma^2 spectrum of an equilibrium")
    _add_actuation(p)
    p.add_argument("--mu", type=finite, required=True)
    p.add_argument("--branch", default="U_A", choices=BRANCHES)
    p.add_argument("--modes", type=int, default=10)
    _add_strip(p, models=static, default="euler-beam")
    add_json_flag(p)
    add_plot_flag(p, "the eigenvalues sigma^2 of the modes")
    p.set_defaults(func=_spectrum)

    p = sub.add_parser("normal-form", help="amplitude-equation coefficients at mu*")
    _add_actuation(p)
    add_json_flag(p)
    p.set_defaults(func=_normal_form)

    p = sub.add_parser("simulate", help="simulate an impulse response, write CSV t,w")
    _add_actuation(p)
    p.add_argument("--mu", type=finite, required=True)
    p.add_argument("--branch", default="U_A", choices=BRANCHES)
    p.add_argument("--damping", type=finite, default=2e-4)
    p.add_argument("--duration", type=finite, default=None)
    p.add_argument("--dt", type=finite, default=None)
    p.add_argument("--kick", type=finite, default=1e-2)
    p.add_argument("--snr", type=finite, default=None, help="noise, dB")
    p.add_argument("--seed", type=int, default=None)
    _add_strip(p, models=MODELS, default="euler-beam")
    p.add_argument("--out", required=True, help="CSV file to write (header t,w)")
    add_json_flag(p)
    p.set_defaults(func=_simulate)

    p = sub.add_parser("snap", help="snap-through past the transition (the paper's protocol)")
    _add_actuation(p)
    p.add_argument("--dmu", type=finite, required=True,
                   help="distance from mu* (> 0): right of mu* (asymmetric, symmetric), left "
                        "of it (antisymmetric, from S_B)")
    p.add_argument("--duration", type=finite, default=None,
                   help="record length (time units); default: 4 normal-form snap times")
    p.add_argument("--damping", type=finite, default=2e-4)
    _add_strip(p, models=static, default="euler-beam")
    p.add_argument("--out", default=None, help="CSV file (t, amplitude) to write")
    add_json_flag(p)
    add_plot_flag(p, "A(t) after the release with the snap time")
    p.set_defaults(func=_snap)


def beam_summary() -> dict:
    """The simulator part of the demo: transitions, U_A spectrum along mu, one response (the
    :class:`~service.schemas.sim.BeamSummary` document)."""
    from service import convert
    from sim import simulate
    from sim.euler_beam import bifurcation, spectrum
    from sim.scene import Scene

    acts = ("asymmetric", "symmetric", "antisymmetric")
    bifs = [bifurcation(act) for act in acts]
    spectra = [(b.actuation, frac * b.mu_star,
                spectrum(b.actuation, frac * b.mu_star, "U_A", modes=2).sigma2)
               for b in bifs for frac in (0.0, 0.5, 0.9, 0.99, 0.999)]  # fmt: skip
    sig = simulate(Scene(actuation="asymmetric", mu=1.5, kick=1e-3, snr_db=40.0, seed=1))
    return convert.beam_summary(bifs, spectra, sig).model_dump(mode="json")


def beam_summary_text(doc: dict) -> str:
    lines = ["Transitions of the Euler beam (U_A branch driven by mu):"]
    for t in doc["transitions"]:
        lines.append(f"  {t['actuation']:14} {t['transition']:24} mu* = {t['mu_star']:.10f}")
        for s in t["secondary"]:
            lines.append(f"  {'':14} secondary {s['transition']:14} mu2* = {s['mu_star']:.10f}")
    lines.append("Fundamental of U_A slows down as mu -> mu* (sqrt|sigma^2|):")
    for row in doc["spectrum_U_A"]:
        lines.append(
            f"  {row['actuation']:14} mu = {row['mu']:.6f}"
            f"  omega = {abs(row['sigma2'][0]) ** 0.5:10.4f}"
        )
    r = doc["impulse_response"]
    lines.append(
        f"Impulse response ({r['actuation']}, mu = {r['mu']}): {r['samples']} samples, "
        f"dt = {r['dt']:.3g}, W(1/4) static {r['w_static']:.5f}, range "
        f"[{r['w_min']:.5f}, {r['w_max']:.5f}]"
    )
    return "\n".join(lines)
