"""Simulator commands: bifurcation, equilibria, spectrum, normal-form, simulate."""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

from service.cli._common import CliError, add_json_flag, bad, emit, finite
from sim.scene import ACTUATIONS, BRANCHES, SceneError


def _add_actuation(p: argparse.ArgumentParser) -> None:
    p.add_argument("--actuation", required=True, choices=ACTUATIONS, help="end rotation mode")


def _beam_errors(fn):
    def wrapper(args):
        from sim.euler_beam import BeamError

        try:
            return fn(args)
        except (BeamError, SceneError) as exc:
            raise CliError(str(exc)) from None

    return wrapper


@_beam_errors
def _bifurcation(args: argparse.Namespace) -> int:
    if args.model == "cosserat":
        from sim import cosserat

        kw = {"end_shortening": args.end_shortening, "slenderness": args.slenderness}
        if args.elements is not None:
            kw["elements"] = args.elements
        doc = cosserat.bifurcation(args.actuation, **kw).to_dict()
    else:
        from sim.euler_beam import bifurcation

        doc = bifurcation(args.actuation).to_dict()
    lines = [f"{doc['actuation']}: {doc['transition']} at mu* = {doc['mu_star']:.12f}"]
    lines += [
        f"  secondary {s['transition']} at mu* = {s['mu_star']:.12f}" for s in doc["secondary"]
    ]
    emit(doc, json_mode=args.json, text="\n".join(lines))
    return 0


@_beam_errors
def _equilibria(args: argparse.Namespace) -> int:
    from sim.euler_beam import equilibria

    eqs = equilibria(args.actuation, args.mu)
    doc = {"actuation": args.actuation, "mu": args.mu, "equilibria": [e.to_dict() for e in eqs]}
    rows = [f"{'branch':6} {'Lambda':>10} {'W(1/2)':>10} {'W(1/4)':>10} {'energy':>10} stable"]
    rows += [
        f"{e['branch']:6} {e['lambda']:10.6f} {e['w_half']:10.6f} {e['w_quarter']:10.6f} "
        f"{e['energy']:10.4f} {e['stable']}"
        for e in doc["equilibria"]
    ]
    emit(doc, json_mode=args.json, text="\n".join(rows))
    return 0


@_beam_errors
def _spectrum(args: argparse.Namespace) -> int:
    from sim.euler_beam import spectrum

    if not 1 <= args.modes <= 30:
        raise bad("--modes", args.modes, "must be between 1 and 30")
    sp = spectrum(args.actuation, args.mu, args.branch, modes=args.modes)
    doc = sp.to_dict()
    rows = [f"{args.branch} at mu = {args.mu}: sigma^2 (omega)"]
    rows += [f"  {s:16.6f}  ({w:.6f})" for s, w in zip(doc["sigma2"], doc["omega"])]
    emit(doc, json_mode=args.json, text="\n".join(rows))
    return 0


@_beam_errors
def _normal_form(args: argparse.Namespace) -> int:
    from sim.normal_form import normal_form

    doc = normal_form(args.actuation).to_dict()
    emit(doc, json_mode=args.json, text=f"{doc['transition']}: {doc['coefficients']}")
    return 0


@_beam_errors
def _simulate(args: argparse.Namespace) -> int:
    from sim import simulate
    from sim.scene import Scene

    fields = dict(
        actuation=args.actuation,
        mu=args.mu,
        branch=args.branch,
        damping=args.damping,
        kick=args.kick,
        duration=args.duration,
        dt=args.dt,
        snr_db=args.snr,
        seed=args.seed,
    )
    for name in ("end_shortening", "slenderness", "elements"):
        if getattr(args, name) is not None:
            fields[name] = getattr(args, name)
    scene = Scene(**fields)
    sig = simulate(scene, args.model)
    out = Path(args.out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        with out.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["t", "w"])
            for ti, wi in zip(sig.t, sig.w):
                w.writerow([repr(float(ti)), repr(float(wi))])
    except OSError as exc:
        raise bad("--out", args.out, f"cannot be written: {exc.strerror}") from None
    doc = {
        "path": str(out),
        "samples": int(sig.t.size),
        "model": sig.model,
        "actuation": scene.actuation,
        "mu": scene.mu,
        "branch": scene.branch,
        "dt": sig.dt,
        "duration": float(sig.t[-1]),
        "w_static": sig.w_static,
        "sigma2": sig.info.get("sigma2", [None])[0],
    }
    if "auto" in sig.info:
        doc["auto"] = sig.info["auto"]
    emit(doc, json_mode=args.json, text=f"wrote {doc['samples']} samples to {out}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add the simulator sub-commands to ``sub``."""
    p = sub.add_parser("bifurcation", help="mu* and type of the transition")
    _add_actuation(p)
    p.add_argument("--model", default="euler-beam", choices=("euler-beam", "cosserat"))
    p.add_argument("--end-shortening", type=finite, default=1e-2)
    p.add_argument("--slenderness", type=finite, default=1e-3)
    p.add_argument("--elements", type=int, default=None)
    add_json_flag(p)
    p.set_defaults(func=_bifurcation)

    p = sub.add_parser("equilibria", help="every equilibrium on the six branches at mu")
    _add_actuation(p)
    p.add_argument("--mu", type=finite, required=True)
    add_json_flag(p)
    p.set_defaults(func=_equilibria)

    p = sub.add_parser("spectrum", help="sigma^2 spectrum of an equilibrium")
    _add_actuation(p)
    p.add_argument("--mu", type=finite, required=True)
    p.add_argument("--branch", default="U_A", choices=BRANCHES)
    p.add_argument("--modes", type=int, default=10)
    add_json_flag(p)
    p.set_defaults(func=_spectrum)

    p = sub.add_parser("normal-form", help="amplitude-equation coefficients at mu*")
    _add_actuation(p)
    add_json_flag(p)
    p.set_defaults(func=_normal_form)

    p = sub.add_parser("simulate", help="simulate an impulse response, write CSV t,w")
    p.add_argument(
        "--model", default="euler-beam", choices=("euler-beam", "normal-form", "cosserat", "auto")
    )
    _add_actuation(p)
    p.add_argument("--mu", type=finite, required=True)
    p.add_argument("--branch", default="U_A", choices=BRANCHES)
    p.add_argument("--damping", type=finite, default=2e-4)
    p.add_argument("--duration", type=finite, default=None)
    p.add_argument("--dt", type=finite, default=None)
    p.add_argument("--kick", type=finite, default=1e-2)
    p.add_argument("--snr", type=finite, default=None, help="noise, dB")
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--elements", type=int, default=None, help="cosserat only")
    p.add_argument("--end-shortening", type=finite, default=None)
    p.add_argument("--slenderness", type=finite, default=None)
    p.add_argument("--out", required=True, help="CSV file to write (header t,w)")
    add_json_flag(p)
    p.set_defaults(func=_simulate)


def beam_summary() -> dict:
    """The simulator part of the demo: transitions, U_A spectrum along mu, one response."""
    from sim import simulate
    from sim.euler_beam import bifurcation, spectrum
    from sim.scene import Scene

    doc: dict = {"transitions": [], "spectrum_U_A": [], "impulse_response": {}}
    for act in ("asymmetric", "symmetric", "antisymmetric"):
        doc["transitions"].append(bifurcation(act).to_dict())
    for act in ("asymmetric", "symmetric", "antisymmetric"):
        mu_star = bifurcation(act).mu_star
        for frac in (0.0, 0.5, 0.9, 0.99, 0.999):
            sp = spectrum(act, frac * mu_star, "U_A", modes=2)
            doc["spectrum_U_A"].append(
                {"actuation": act, "mu": frac * mu_star, "sigma2": sp.sigma2.tolist()}
            )
    sig = simulate(Scene(actuation="asymmetric", mu=1.5, kick=1e-3, snr_db=40.0, seed=1))
    doc["impulse_response"] = {
        "actuation": "asymmetric",
        "mu": 1.5,
        "samples": int(sig.t.size),
        "dt": sig.dt,
        "w_static": sig.w_static,
        "w_min": float(sig.w.min()),
        "w_max": float(sig.w.max()),
        "sigma2": sig.info["sigma2"][0],
    }
    return doc


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
