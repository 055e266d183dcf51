"""Which h/L reproduces the paper's rod values? Reads a Table 1 atlas (cells.jsonl).

    python examples/table1_answer.py var/atlas-table1/cells.jsonl

For each actuation, mu*(h/L) is interpolated between the atlas's cells (piecewise linear in
(h/L)^2: mu* falls like the extensibility term, ~ h^2) and solved for the paper's value; then
the single h/L that fits the three values best (least squares) and its worst deviation.
"""

from __future__ import annotations

import json
import sys

import numpy as np

PAPER = {"asymmetric": 1.763, "symmetric": 1.973, "antisymmetric": 1.967}


def main(path: str) -> None:
    rows = [json.loads(x) for x in open(path) if x.strip()]
    curves = {}
    for act in PAPER:
        pts = sorted((r["inputs"]["slenderness"], r["results"]["mu_star"],
                      r["results"].get("mu_star_error")) for r in rows
                     if r["status"] == "ok" and r["inputs"]["actuation"] == act)
        h = np.array([p[0] for p in pts])
        mu = np.array([p[1] for p in pts])
        curves[act] = (h, mu)
        print(f"{act:14} h/L: " + " ".join(f"{x:.4g}" for x in h))
        print(f"{'':14} mu*: " + " ".join(f"{x:.5f}" for x in mu))
        print(f"{'':14} est. discretisation error of mu* <= "
              f"{max(p[2] or 0 for p in pts):.1e}")
    print("\npaper's rod value -> h/L of the rectangular strip (dL/L = 1e-2)")
    found = {}
    for act, target in PAPER.items():
        h, mu = curves[act]
        if not mu.min() <= target <= mu.max():
            print(f"  {act:14} {target}: outside [{mu.min():.5f}, {mu.max():.5f}] on this grid")
            continue
        # mu* decreases with h: interpolate h^2 against mu*
        order = np.argsort(mu)
        h2 = np.interp(target, mu[order], (h**2)[order])
        found[act] = float(np.sqrt(h2))
        print(f"  {act:14} {target}: h/L = {found[act]:.5f}")
    fine = np.linspace(min(c[0].min() for c in curves.values()),
                       max(c[0].max() for c in curves.values()), 2001)
    dev = np.array([[np.interp(x**2, c[0] ** 2, c[1]) - PAPER[a] for a, c in curves.items()]
                    for x in fine])
    best = int(np.argmin((dev**2).sum(axis=1)))
    print(f"\none h/L for all three (least squares): h/L = {fine[best]:.5f}; deviations "
          + ", ".join(f"{a} {d:+.4f}" for a, d in zip(PAPER, dev[best])))


if __name__ == "__main__":
    main(sys.argv[1])
