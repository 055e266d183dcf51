"""Progress that tells the truth: one line per stage in logs, 100 % at the end (or a stop said
as such), a compile stage before the numerics, no ETA."""

from __future__ import annotations

import io

import pytest

from service.cli._progress import COMPILE_STAGE, Progress, stage_key, warm_kernels


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_stage_key_ignores_numbers() -> None:
    assert stage_key("mu=0.2 T/T0=1.02") == stage_key("mu=1.7e-3 T/T0=12")
    assert stage_key("detected 3/8") == stage_key("detected 8/8")
    assert stage_key("mu=0.6 T/T0=1.1") != stage_key("mu=0.6 T/T0=1.1 mu*=2.8 [1.6, 4.0]")


def test_log_gets_one_line_per_stage_and_ends_at_100() -> None:
    out = io.StringIO()
    p = Progress("asymmetric", stream=out)
    assert not p.tty
    for k in range(30):  # the warn pipeline's messages: a stage without, then with, mu*
        msg = f"mu={k / 10} T/T0={1 + k / 20}"
        if k >= 4:
            msg += f" mu*={1.78 + 1 / (k + 1)} [{1.7}, {1.9}]"
        p((k + 1) / 40, msg)  # stops at 75 % of its budget (converged early)
    p.close()
    lines = out.getvalue().splitlines()
    assert len(lines) == 3, lines
    assert lines[0].startswith("asymmetric:   2% mu=0.0")
    assert "mu*=" in lines[1]
    assert lines[-1].startswith("asymmetric: 100% done")


def test_a_failure_is_not_reported_as_done() -> None:
    out = io.StringIO()
    p = Progress(stream=out)
    with pytest.raises(ValueError):
        try:
            p(0.3, "detected 3/10")
            raise ValueError("no mode")
        finally:
            p.close()
    text = out.getvalue()
    assert "100%" not in text and "stopped (ValueError)" in text


def test_terminal_bar_ends_at_100_without_eta() -> None:
    out = _Tty()
    p = Progress("sweep", stream=out)
    assert p.tty
    p(0.53, "mu=1.7 T/T0=4")
    p.close()
    text = out.getvalue()
    assert "100%" in text
    assert "<" not in text and "?" not in text  # tqdm's ETA ("<00:10") is not drawn


def test_compile_stage_is_silent_when_nothing_compiles() -> None:
    warm_kernels((), enabled=False)  # whatever the cache held, these kernels are now loaded
    out = io.StringIO()
    seconds = warm_kernels((), stream=out)
    assert out.getvalue() == ""  # "first run only" is not said on a run that compiles nothing
    assert seconds >= 0


def test_compile_stage_is_announced_and_timed_when_a_kernel_compiles(monkeypatch) -> None:
    import numba

    import service.analysis.detect as detect_pkg

    real = detect_pkg.detect

    def detect_compiling(*args, **kw):  # a kernel numba has never seen: a real compilation
        numba.njit(cache=False)(lambda x: x + 1.0)(1.0)
        return real(*args, **kw)

    monkeypatch.setattr(detect_pkg, "detect", detect_compiling)
    out = io.StringIO()
    seconds = warm_kernels((), stream=out)
    lines = out.getvalue().splitlines()
    assert lines[0].startswith(COMPILE_STAGE)
    assert lines[-1].startswith(f"{COMPILE_STAGE}: done in ")
    assert seconds >= 0
