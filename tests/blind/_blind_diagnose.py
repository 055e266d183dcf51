"""Which link of the chain is at fault for one blind campaign: detector, predictor or policy.

``python tests/blind/_blind_diagnose.py FAMILY PLAN SEED DIR [key=value ...]`` writes the
campaign (as ``_blind_sweeps.py`` does), runs ``snapwarn sweep MANIFEST --json`` and then:

1. detector: each measurement's ``sigma2`` against the generator's exact value of EVERY mode at
   that control (the critical one first), in units of the ``sigma2_std`` the product reported
   (``z``); a record read on another mode, or on a blend of two, shows here;
2. predictor: ``snapwarn predict`` on two tables with the product's own ``sigma2_std``: the exact
   critical ``sigma2`` (``exact_table.csv``: the predictor's best case with the detector's stated
   errors) and the detected values (``detected_table.csv``: must reproduce the sweep's answer
   when the policy changed nothing);
3. policy: the sweep's answer against ``predict`` on the detected table (same digits: the policy
   and reconcile changed nothing).

Each answer is judged like the trials (:func:`_blind_trials.judge`). The product is driven only
through its CLI; nothing here imports ``sim`` or ``service``.
"""

from __future__ import annotations

import ast
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

import _blind_sweeps as S  # noqa: E402
import _blind_trials as T  # noqa: E402


def exact_modes(camp: S.Campaign) -> list[tuple[float, float, list[float]]]:
    """Per record (recording order): control (its unit), the critical mode's exact ``sigma2``
    and every mode's (1/s^2, the critical one first)."""
    oms = camp.omega_scale()
    out = []
    items = [(p, False) for p in camp.controls] + [(p, True) for p in camp.past]
    for p, beyond in items:
        st = camp.state(p, beyond and S._snaps(camp.structure))
        s2 = [-float(o) * oms**2 for o in st.omega2]
        crit = s2[st.critical]
        out.append((p * camp.load_scale, crit, [crit] + [v for v in s2 if v != crit]))
    return out


def _table(path: Path, rows: list[tuple[float, float, float]]) -> Path:
    with open(path, "w") as fh:
        fh.write("mu,sigma2,sigma2_std\n")
        for mu, s2, sd in rows:
            fh.write(f"{mu!r},{s2!r},{sd!r}\n")
    return path


def _line(name: str, ans: T.Answer, truth: S.Truth) -> str:
    v = T.judge(ans, truth)
    iv = "none" if ans.interval is None else f"[{ans.interval[0]:.10g}, {ans.interval[1]:.10g}]"
    return (f"{name}: {ans.transition} mu* {ans.mu_star!r} {iv} flags {list(ans.flags)} -> "
            f"verdict {v.type}, covered {v.covered}, confident {v.confident}")


def diagnose(family: str, plan: str, seed: int, folder: Path, **over) -> dict:  # noqa: ANN003
    camp = S.campaign(family, plan, seed, **over)
    truth = camp.write(Path(folder))
    print(f"{family}/{plan}/{seed}: truth {truth.kind} mu* = {truth.mu_star!r} "
          f"{truth.control_unit}; {truth.params}")
    ans = T.cli_sweep(truth.manifest)
    if not ans.ok or ans.transition is None:
        print(f"sweep gave no prediction: {ans.error or ans.flags}")
        return {"sweep": ans}
    modes = exact_modes(camp)
    rows_exact, rows_det, zs = [], [], []
    print("detector: each usable control's sigma2 (repeats averaged by the product) against the "
          "exact modes, z = (detected - exact) / reported std")
    for m in ans.measurements:
        mu, s2, sd = float(m["mu"]), float(m["sigma2"]), float(m["sigma2_std"] or math.nan)
        at = [x for x in modes if abs(x[0] - mu) <= 1e-9 * max(1.0, abs(mu))]
        if not at:
            continue
        crit, every = at[0][1], at[0][2]
        z = [(s2 - e) / sd for e in every]
        zs.append(z[0])
        rows_exact.append((mu, crit, sd))
        rows_det.append((mu, s2, sd))
        others = ", ".join(f"{e:.6g} (z {zz:+.3g})" for e, zz in zip(every[1:], z[1:],
                                                                      strict=True))
        print(f"  mu {mu:<14.10g} detected {s2:<14.8g} +- {sd:<10.4g} critical {crit:<14.8g} "
              f"z {z[0]:+9.3g}   other modes: {others}")
    chi2 = sum(z * z for z in zs)
    print(f"  sum z^2 over {len(zs)} controls: {chi2:.4g} (about {len(zs)} when the stated "
          "errors are right)")
    ex = T.cli_predict(_table(Path(folder) / "exact_table.csv", rows_exact))
    de = T.cli_predict(_table(Path(folder) / "detected_table.csv", rows_det))
    print(_line("sweep                          ", ans, truth))
    print(_line("predict, detected sigma2       ", de, truth))
    print(_line("predict, exact sigma2 (same std)", ex, truth))
    same = de.mu_star == ans.mu_star and de.interval == ans.interval
    print(f"policy: the sweep's answer {'IS' if same else 'is NOT'} predict's on the detected "
          "table (to the last digit)")
    return {"sweep": ans, "detected": de, "exact": ex, "z": zs, "chi2": chi2, "truth": truth}


if __name__ == "__main__":
    a = sys.argv[1:]
    kw = {k: ast.literal_eval(v) for k, v in (x.split("=", 1) for x in a[4:])}
    diagnose(a[0], a[1], int(a[2]), Path(a[3]), **kw)
