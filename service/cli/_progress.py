"""Progress on stderr that tells the truth.

- Long numerics first load their numba kernels (compiled once by ``make setup``, about a second
  from the cache). :func:`warm_kernels` runs each kernel once on a tiny input before the bars;
  only when numba must compile one (a cache missing or out of date: tens of seconds) does it
  say so, as its own stage "compiling kernels (first run only)", so that no bar sits at 0 %
  with a made-up ETA while the compiler works.
- A bar shows the fraction done and the elapsed time, never an ETA (the steps of a sweep do not
  take equal times), and ends at 100 % when the work ends, also when a sweep stops early
  (converged before its budget of measurements).
- On a terminal the bar redraws in place; in a log (stderr not a TTY) each *stage* is one line:
  a new line is written only when the message's words change (numbers ignored), with the
  percentage and the elapsed time, and one closing line.
"""

from __future__ import annotations

import re
import sys
import time
from typing import Any, TextIO

COMPILE_STAGE = "compiling kernels (first run only)"
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
BAR_FORMAT = "{desc}{percentage:3.0f}%|{bar}| [{elapsed}]{postfix}"  # postfix: ", message"


def stage_key(message: str) -> str:
    """The words of a progress message (numbers removed): equal keys, same stage."""
    return " ".join(_NUMBER.sub("#", message).split())


class Progress:
    """``progress(fraction, message)`` callable for the numerics, drawn on ``stream``.

    Parameters
    ----------
    label : str
        Prefix of the bar / of each log line (e.g. the actuation).
    stream : file, optional
        stderr by default.
    tty : bool, optional
        Redraw a bar in place (default: ``stream.isatty()``); else one line per stage.
    position : int
        Row of the bar when several are drawn at once (tqdm's ``position``).
    """

    def __init__(
        self,
        label: str = "",
        *,
        stream: TextIO | None = None,
        tty: bool | None = None,
        position: int = 0,
    ) -> None:
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.tty = self.stream.isatty() if tty is None else tty
        self.t0 = time.monotonic()
        self.fraction = 0.0
        self.message = ""
        self._key: str | None = None
        self._bar: Any = None
        self.closed = False
        if self.tty:
            from tqdm import tqdm

            self._bar = tqdm(total=100, file=self.stream, desc=f"{label} " if label else "",
                             bar_format=BAR_FORMAT, position=position, leave=True,
                             dynamic_ncols=True)  # fmt: skip

    def _line(self, text: str) -> None:
        prefix = f"{self.label}: " if self.label else ""
        self.stream.write(f"{prefix}{text}\n")
        self.stream.flush()

    def __call__(self, fraction: float, message: str) -> None:
        """Report ``fraction`` (0..1) done and what is being done."""
        if self.closed:
            return
        self.fraction = min(1.0, max(self.fraction, float(fraction)))
        self.message = str(message)
        if self._bar is not None:
            self._bar.n = round(100 * self.fraction)
            self._bar.set_postfix_str(self.message[:70], refresh=False)
            self._bar.refresh()
            return
        key = stage_key(self.message)
        if key != self._key:
            self._key = key
            elapsed = time.monotonic() - self.t0
            self._line(f"{100 * self.fraction:3.0f}% {self.message} ({elapsed:.1f} s)")

    def close(self, message: str = "done") -> None:
        """End at 100 % (the work is over even when it stopped before its budget).

        Called while an exception propagates (a ``finally`` clause), it ends as :meth:`fail`
        instead: the bar never claims a completion that did not happen.
        """
        if self.closed:
            return
        exc = sys.exc_info()[0]
        if exc is not None:
            self.fail(f"stopped ({exc.__name__})")
            return
        elapsed = time.monotonic() - self.t0
        if self._bar is not None:
            self._bar.n = 100
            self._bar.set_postfix_str(message[:70], refresh=False)
            self._bar.refresh()
            self._bar.close()
        else:
            self._line(f"100% {message} ({elapsed:.1f} s)")
        self.closed = True

    def fail(self, message: str = "failed") -> None:
        """Stop without claiming completion."""
        if self.closed:
            return
        if self._bar is not None:
            self._bar.set_postfix_str(message[:70], refresh=False)
            self._bar.close()
        else:
            self._line(f"{100 * self.fraction:3.0f}% {message}")
        self.closed = True


def make_progress(enabled: bool, label: str = "", **kw: Any) -> Progress | None:
    """A :class:`Progress` or None (``--no-progress``)."""
    return Progress(label, **kw) if enabled else None


def warm_kernels(models: tuple[str, ...] = (), *, enabled: bool = True,
                 stream: TextIO | None = None) -> float:  # fmt: skip
    """Run the detector, the predictor and the simulators of ``models`` once on tiny inputs,
    so that no progress bar sits at 0 % while numba works. Their kernels load from numba's
    cache (filled by ``make setup``: ``service.warmup``); only when one must be compiled (a
    cache missing or out of date) is the stage "compiling kernels (first run only)" written,
    with its time when done. Returns the seconds it took."""
    import numpy as np

    from service.warmup import watch_compiles

    t0 = time.monotonic()
    out = stream if stream is not None else sys.stderr
    tty = out.isatty()
    said: list[bool] = []

    def announce() -> None:
        if enabled:
            out.write(f"{COMPILE_STAGE}..." + ("" if tty else "\n"))
            out.flush()
            said.append(True)

    with watch_compiles(announce):
        from service.analysis.detect import detect
        from service.analysis.predict import predict

        t = np.arange(400) * 0.05
        rng = np.random.default_rng(0)
        detect(np.exp(-0.05 * t) * np.cos(t) + 1e-3 * rng.standard_normal(t.size), dt=0.05)
        mu = np.linspace(0.0, 1.6, 6)
        predict(mu, -np.sqrt(2.0 - mu))  # a fold's law: sigma^2 ~ -(mu* - mu)^(1/2)
        if models:
            from sim import simulate
            from sim.scene import Scene

            for model in models:
                if model not in ("euler-beam", "normal-form"):
                    continue  # the Cosserat rod loads its kernels during its first measurement
                simulate(Scene(actuation="asymmetric", mu=0.5, snr_db=40.0, seed=1), model)
    seconds = time.monotonic() - t0
    if said:
        out.write(f"{chr(13) if tty else ''}{COMPILE_STAGE}: done in {seconds:.1f} s\n")
        out.flush()
    return seconds
