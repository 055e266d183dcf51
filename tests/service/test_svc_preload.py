"""The simulators' packages are imported before a server serves.

The backends import their packages lazily; two worker threads importing a package and one of
its submodules at once deadlock on Python's module locks, and the import system hands one of
them a partially initialised module (an ImportError: two HTTP 500s the fuzz found on a fresh
PostgreSQL-backed server). Each check runs in a fresh interpreter, where nothing is imported
yet: the race itself (which ``preload`` must prevent), and the server's lifespan calling it.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

_RACE = """
import sys, threading
{pre}
errors = []
barrier = threading.Barrier(4)

def submodule_first():
    barrier.wait()
    try:
        from sim.cosserat.dynamics import steps_for  # noqa: F401
    except Exception as e:
        errors.append(repr(e))

def package_first():
    barrier.wait()
    try:
        from sim.cosserat import statics  # noqa: F401
    except Exception as e:
        errors.append(repr(e))

threads = [threading.Thread(target=f) for f in (submodule_first, package_first) * 2]
for t in threads:
    t.start()
for t in threads:
    t.join()
print(len(errors))
"""


def _run(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, timeout=120, check=True)  # fmt: skip
    return out.stdout.strip()


def test_preloaded_packages_survive_concurrent_lazy_imports() -> None:
    """Five fresh interpreters each: with ``preload`` first, no thread's lazy import fails.
    (Without it the same race failed in 6 of 6 interpreters while this was written.)"""
    for _ in range(5):
        assert _run(_RACE.format(pre="from sim.backends import preload; preload()")) == "0"


def test_the_server_lifespan_preloads_the_simulators() -> None:
    code = (
        "import sys\n"
        "from fastapi.testclient import TestClient\n"
        "from service.api.app import create_app\n"
        "from service.api.settings import Settings\n"
        "before = 'sim.cosserat' in sys.modules\n"
        "with TestClient(create_app(Settings(db_url='sqlite://', warm_pool=False,"
        " run_jobs=False))):\n"
        "    after = all(m in sys.modules for m in"
        " ('sim.cosserat', 'sim.euler_beam', 'sim.normal_form'))\n"
        "print(before, after)\n"
    )
    assert _run(code) == "False True"
