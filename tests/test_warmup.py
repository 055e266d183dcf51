"""The kernel warm-up (``python -m service.warmup``, run by ``make setup``): every public path
runs, and afterwards numba's cache holds every kernel they need (a second run compiles nothing,
in a fresh process that can only load from the cache)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from service import warmup


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "service.warmup", *args], capture_output=True,
                          text=True, timeout=1200)  # fmt: skip


def test_a_second_warm_up_compiles_nothing() -> None:
    first = _run()  # compiles what the cache lacks (nothing after `make setup`)
    assert first.returncode == 0, first.stderr  # 2: a path failed (named in stderr)
    second = _run("--check", "-v")
    assert second.returncode == 0, second.stderr  # 1: something compiled again
    assert "numba kernels: 0 compiled" in second.stderr


def test_the_paths_cover_the_product() -> None:
    names = [n for n, _ in warmup.paths()]
    for needed in ("detect[varpro]", "detect[ambient]", "predict[auto]", "classify",
                   "predict[saddle-node]", "sweep_from_signals", "live.update",
                   "euler-beam.simulate[nonlinear]", "normal-form.simulate",
                   "cosserat.simulate"):  # fmt: skip
        assert needed in names
    assert not [n for n, _ in warmup.paths(models=(), analysis=True) if "simulate" in n]


def test_watch_compiles_sees_a_compilation_and_only_one() -> None:
    import numba

    calls: list[int] = []
    f = numba.njit(cache=False)(lambda x: 2.0 * x)
    with warmup.watch_compiles(lambda: calls.append(1)) as compiled:
        f(1.0)
        f(2.0)  # same signature: no second compilation
    assert len(compiled) == 1 and "float64" in compiled[0]
    assert calls == [1]
    with warmup.watch_compiles() as compiled:
        f(3.0)
    assert compiled == []


def test_cli_rejects_an_unknown_model() -> None:
    with pytest.raises(SystemExit):
        warmup.main(["--models", "no-such-model"])


def test_the_image_carries_a_warm_cache() -> None:
    """The Docker image compiles its kernels at build time into the cache its commands use
    (the engine is not available to the tests: the files are checked instead)."""
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    docker = (repo / "Dockerfile").read_text()
    install = docker.index('pip install ".[postgres]"')
    warm = docker.index("python -m service.warmup")
    assert install < warm < docker.index("USER snapwarn")
    assert "python -m service.warmup --check" in docker
    assert "NUMBA_CACHE_DIR=/app/numba-cache" in docker
    assert "chown -R snapwarn /app/numba-cache" in docker
    # the compose file's containers keep the image's cache (no other NUMBA_CACHE_DIR)
    assert "NUMBA_CACHE_DIR" not in (repo / "docker-compose.yml").read_text()
    # make setup warms the checkout's cache the same way
    assert "python -m service.warmup" in (repo / "Makefile").read_text()
