"""Fill numba's cache: every kernel the product runs, compiled once (at install), not at first use.

The numerics' kernels are ``@njit(cache=True)``: numba compiles a kernel for each signature it
is called with and keeps the machine code in its cache (``__pycache__`` next to the source, or
``NUMBA_CACHE_DIR``), valid while the source file keeps its modification time and size. Rather
than list kernels and guess their signatures, :func:`warm` calls each *public path* once on a
tiny input -- the detector's methods and record kinds, the predictor and the classifier on
every law, a lab sweep, a live update, the Euler beam (statics, modal and nonlinear responses),
the normal form and the Cosserat rod -- so that exactly the specialisations the product uses
are compiled. ``make setup`` and the Docker image build run ``python -m service.warmup``; a
second run then compiles nothing (``--check`` fails if it does), and ``snapwarn serve`` runs
the same warm-up in its analysis workers before it reports ready on ``/healthz``.

Numerics only: this module never imports the web stack.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from collections.abc import Callable, Iterable
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

#: The simulators a full warm-up covers (``sim.MODELS`` less "auto").
SIM_MODELS = ("normal-form", "euler-beam", "cosserat")


@dataclass(frozen=True)
class WarmReport:
    """What one warm-up did.

    Attributes
    ----------
    seconds : float
        Wall time of the warm-up.
    compiled : tuple of str
        The kernels numba compiled (``module.function(signature)``): those its cache did not
        hold. Empty on a warm install.
    failed : tuple of str
        The paths that raised (``name: error``): reported, never raised (warming is best
        effort; the same call fails again where it is used, with its own error).
    """

    seconds: float
    compiled: tuple[str, ...] = ()
    failed: tuple[str, ...] = ()

    @property
    def cold(self) -> bool:
        """True when something had to be compiled."""
        return bool(self.compiled)


# ------------------------------------------------------------------ watching numba compile
_WATCH_LOCK = threading.Lock()


@dataclass
class _CompileWatch:
    """Counts numba compilations (the ``numba:compile`` event fires on a cache miss only)."""

    on_first: Callable[[], None] | None = None
    compiled: list[str] = field(default_factory=list)

    def listener(self) -> Any:
        from numba.core import event

        watch = self

        class _Listener(event.Listener):
            def on_start(self, ev: Any) -> None:
                data = ev.data or {}
                disp = data.get("dispatcher")
                py = getattr(disp, "py_func", None)
                name = (f"{py.__module__}.{py.__qualname__}" if py is not None
                        else str(disp))  # fmt: skip
                with _WATCH_LOCK:
                    first = not watch.compiled
                    watch.compiled.append(f"{name}{data.get('args', '')}")
                if first and watch.on_first is not None:
                    watch.on_first()

            def on_end(self, ev: Any) -> None:
                pass

        return _Listener()


@contextmanager
def watch_compiles(on_first: Callable[[], None] | None = None) -> Any:
    """Context manager yielding the list of kernels numba compiles inside it.

    ``on_first`` is called (once) when the first compilation starts: e.g. to print "compiling
    kernels (first run only)" only when that is true.
    """
    from numba.core import event

    watch = _CompileWatch(on_first)
    with event.install_listener("numba:compile", watch.listener()):
        yield watch.compiled


# --------------------------------------------------------------------------- the paths
def _ringing(n: int = 600, dt: float = 0.05, seed: int = 0) -> Any:
    """A two-mode damped ringing with an offset and a little noise (float64)."""
    import numpy as np

    t = np.arange(n) * dt
    rng = np.random.default_rng(seed)
    return (0.3 + np.exp(-0.04 * t) * np.cos(1.3 * t) + 0.3 * np.exp(-0.1 * t) * np.sin(3.1 * t)
            + 1e-3 * rng.standard_normal(n))  # fmt: skip


def _detect_paths() -> list[tuple[str, Callable[[], Any]]]:
    import numpy as np

    from service.analysis.detect import detect

    w = _ringing()
    rng = np.random.default_rng(1)
    ambient = np.zeros(1200)
    e = rng.standard_normal(1200)
    for k in range(2, 1200):  # an AR(2) resonance driven by noise
        ambient[k] = 1.9 * ambient[k - 1] - 0.95 * ambient[k - 2] + e[k]
    out = [(f"detect[{m}]", lambda m=m: detect(w, dt=0.05, method=m))
           for m in ("varpro", "esprit", "fft", "fft-parabolic")]  # fmt: skip
    out.append(("detect[common_damping]", lambda: detect(w, dt=0.05, common_damping=True)))
    out.append(("detect[ambient]", lambda: detect(ambient, dt=0.05, kind="ambient")))
    out.append(("detect[float32]", lambda: detect(w.astype(np.float32), dt=0.05)))
    return out


def _law(mu: Any, mu_star: float, a: float) -> Any:
    return -((mu_star - mu) ** (2 * a))


def _predict_paths() -> list[tuple[str, Callable[[], Any]]]:
    import numpy as np

    from service.analysis.classify import classify
    from service.analysis.predict import predict

    rng = np.random.default_rng(2)
    mu = np.linspace(0.0, 1.6, 8)
    fold = _law(mu, 2.0, 0.25) * (1 + 1e-3 * rng.standard_normal(mu.size))
    pitch = _law(mu, 2.0, 0.5) * (1 + 1e-3 * rng.standard_normal(mu.size))
    std = 1e-3 * np.abs(fold)
    ws = 0.1 + 0.05 * np.sqrt(2.0 - mu)
    out: list[tuple[str, Callable[[], Any]]] = [
        ("predict[auto]", lambda: predict(mu, fold)),
        ("predict[auto, std, static]",
         lambda: predict(mu, fold, sigma2_std=std, w_static=ws, w_static_std=1e-4)),
        ("predict[omega, damping]",
         lambda: predict(mu, omega=np.sqrt(-fold), damping=1e-3)),
        ("predict[a]", lambda: predict(mu, pitch, a=0.5)),
        ("classify", lambda: classify(mu, pitch, w_static=ws)),
    ]
    for tr in ("saddle-node", "subcritical-pitchfork", "supercritical-pitchfork", "pitchfork"):
        data = fold if tr == "saddle-node" else pitch
        out.append((f"predict[{tr}]", lambda tr=tr, data=data: predict(mu, data, transition=tr)))
    return out


def _sweep_paths() -> list[tuple[str, Callable[[], Any]]]:
    """A lab sweep from records and a live update: the glue between detect and predict."""
    import numpy as np

    from service.analysis import live
    from service.analysis.pipeline import sweep_from_signals

    dt = 0.05
    t = np.arange(800) * dt
    mus = np.linspace(0.0, 1.5, 6)
    records = [(np.exp(-0.02 * t) * np.cos(np.sqrt(2.0 - m) ** 0.5 * t) + 1e-3 * np.cos(7 * t),
                dt, float(m)) for m in mus]  # fmt: skip

    def live_sweep() -> Any:
        prev: list[Any] = []
        up = None
        for w, step, c in records:
            up = live.update(prev, w, dt=step, control=c)
            prev.append(up.record)
        return up

    return [("sweep_from_signals", lambda: sweep_from_signals(records)),
            ("live.update", live_sweep)]  # fmt: skip


def _sim_paths(models: Iterable[str]) -> list[tuple[str, Callable[[], Any]]]:
    from sim import simulate
    from sim.backends import BACKENDS
    from sim.scene import Scene

    out: list[tuple[str, Callable[[], Any]]] = []
    for model in models:
        if model not in SIM_MODELS:
            continue
        be = BACKENDS[model]
        scene = Scene(actuation="asymmetric", mu=0.5, snr_db=40.0, seed=1, rtol=1e-2,
                      duration=2.0, dt=1e-2)  # fmt: skip
        out.append((f"{model}.bifurcation", lambda be=be, s=scene: be.bifurcation(s)))
        out.append((f"{model}.simulate", lambda m=model, s=scene: simulate(s, m)))
        if model == "euler-beam":
            out.append((f"{model}.simulate[nonlinear]",
                        lambda s=scene: simulate(s, "euler-beam", method="nonlinear")))
            out.append((f"{model}.equilibria", lambda be=be, s=scene: be.equilibria(s)))
    return out


def paths(models: Iterable[str] = SIM_MODELS, *, analysis: bool = True
          ) -> list[tuple[str, Callable[[], Any]]]:  # fmt: skip
    """The (name, call) pairs a warm-up runs: the analysis paths, then the simulators'."""
    out: list[tuple[str, Callable[[], Any]]] = []
    if analysis:
        out += _detect_paths() + _predict_paths() + _sweep_paths()
    return out + _sim_paths(models)


def warm(
    models: Iterable[str] = SIM_MODELS,
    *,
    analysis: bool = True,
    on_compile: Callable[[], None] | None = None,
    on_path: Callable[[str], None] | None = None,
) -> WarmReport:
    """Run every public path once on a tiny input: numba compiles what its cache lacks.

    Parameters
    ----------
    models : iterable of str
        Simulators to warm (of :data:`SIM_MODELS`); the analysis is warmed with ``analysis``.
    on_compile : callable, optional
        Called once, when the first kernel is compiled (nothing is compiled on a warm cache).
    on_path : callable, optional
        Called with each path's name before it runs (progress).

    Returns
    -------
    WarmReport
    """
    import warnings

    t0 = time.monotonic()
    failed: list[str] = []
    with watch_compiles(on_compile) as compiled, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, call in paths(models, analysis=analysis):
            if on_path is not None:
                on_path(name)
            try:
                call()
            except Exception as exc:  # noqa: BLE001 - best effort, reported
                failed.append(f"{name}: {type(exc).__name__}: {exc}")
    return WarmReport(time.monotonic() - t0, tuple(compiled), tuple(failed))


def main(argv: list[str] | None = None) -> int:
    """``python -m service.warmup [--check] [--models ...]``: fill numba's cache."""
    p = argparse.ArgumentParser(prog="python -m service.warmup", description=__doc__.split("\n")[0])
    p.add_argument("--models", nargs="*", default=list(SIM_MODELS), choices=SIM_MODELS,
                   help="simulators to warm (default: all)")  # fmt: skip
    p.add_argument("--check", action="store_true",
                   help="fail (exit 1) if anything had to be compiled (the cache was not full)")
    p.add_argument("-v", "--verbose", action="store_true", help="list the compiled kernels")
    args = p.parse_args(argv)
    t_cpu = time.process_time()

    def say(text: str) -> None:
        sys.stderr.write(text + "\n")
        sys.stderr.flush()

    rep = warm(args.models, on_path=(lambda n: say(f"  {n}")) if args.verbose else None)
    where = os.environ.get("NUMBA_CACHE_DIR") or "__pycache__ next to the sources"
    say(f"numba kernels: {len(rep.compiled)} compiled, cache in {where} "
        f"({rep.seconds:.1f} s wall, {time.process_time() - t_cpu:.1f} s CPU)")  # fmt: skip
    if args.verbose:
        for k in rep.compiled:
            say(f"  compiled {k}")
    for f in rep.failed:
        say(f"  warm-up path failed: {f}")
    if rep.failed:
        return 2
    if args.check and rep.cold:
        say("  --check: the cache was not full (see above)")
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
