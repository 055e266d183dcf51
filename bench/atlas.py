"""Where methods fail, for users: the detector's atlas and the predictor's, in one run.

    python bench/atlas.py [--quick]

Runs ``bench/atlas_detector.py``'s ``run(quick)`` (FFT peak, ESPRIT, variable projection:
error / Cramer-Rao bound and failure rate over SNR x cycles x damping) when present, and
``bench/atlas_predictor.py``'s (ours against the paper's rule over stop distance x grid step x
noise x actuation). Heatmaps (PNG) and tables (CSV) land in bench/results/.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))


def _load(name: str):
    path = HERE / f"{name}.py"
    if not path.exists():
        return None
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def run(quick: bool = False) -> list[Path]:
    """Run both atlases; return every path written."""
    out: list[Path] = []
    for name in ("atlas_detector", "atlas_predictor"):
        mod = _load(name)
        if mod is None:
            print(f"{name}.py not found: skipped")
            continue
        paths = mod.run(quick=quick)
        out.extend(Path(p) for p in paths)
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small grids (minutes)")
    args = ap.parse_args(argv)
    for p in run(args.quick):
        print(p)


if __name__ == "__main__":
    main()
