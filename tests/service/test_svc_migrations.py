"""Alembic migrations: the head equals the models (a table added without a migration fails
here), and an old database with data in it is upgraded without losing anything."""

from __future__ import annotations

import importlib
import pkgutil

import pytest
from sqlalchemy import inspect, text

import service.api.storage as storage
from service.api import migrations
from service.api.storage import Base, Store, make_engine


def _all_tables() -> None:
    for info in pkgutil.iter_modules(storage.__path__):
        importlib.import_module(f"service.api.storage.{info.name}")


def test_head_equals_the_models(new_db) -> None:  # noqa: ANN001
    """`upgrade head` on an empty database gives exactly the tables, columns and indexes of
    the models (every module of service.api.storage)."""
    from alembic.autogenerate import compare_metadata
    from alembic.migration import MigrationContext

    _all_tables()
    engine = make_engine(new_db("head"))
    assert migrations.upgrade(engine) == migrations.head()
    with engine.connect() as conn:
        diff = compare_metadata(MigrationContext.configure(conn), Base.metadata)
    engine.dispose()
    assert diff == [], f"the models differ from the migrations' head (add a migration): {diff}"


def test_an_old_database_is_upgraded_with_its_data(new_db) -> None:  # noqa: ANN001
    """A database made before migrations (the first revision's schema, no alembic_version),
    holding a signal, a running job and a sweep, is upgraded to the head at startup."""
    url = new_db("old")
    engine = make_engine(url)
    migrations.upgrade(engine, migrations.FIRST)
    w = bytes(range(16))
    with engine.begin() as c:
        c.execute(text("DROP TABLE alembic_version"))  # as create_all left it
        c.execute(
            text(
                "INSERT INTO signals (id, name, n, dt, t0, metadata, source, w, has_t, sha256,"
                " created_at) VALUES ('s1', 'old', 2, 0.5, 0, '{\"k\": 1}', 'json', :w, :f,"
                " 'abc', '2025-01-01 00:00:00')"
            ),
            {"w": w, "f": False},
        )
        c.execute(
            text(
                "INSERT INTO jobs (id, kind, status, params, fraction, message, attempts, owner,"
                " created_at) VALUES ('j1', 'sweep-signals', 'running', '{}', 0.5, 'half', 1,"
                " 'host:123:abcd', '2025-01-01 00:00:00')"
            )
        )
        c.execute(
            text(
                "INSERT INTO sweeps (id, name, request, created_at) VALUES ('j1', 'sw', '{}',"
                " '2025-01-01 00:00:00')"
            )
        )
    engine.dispose()
    store = Store(url)
    store.create_all()  # what the server does at startup
    assert migrations.current(store.engine) == migrations.head()
    sig = store.get_signal("s1")
    assert sig is not None and sig.row.owner == "local" and sig.row.meta == {"k": 1}
    assert sig.w.tobytes() == w and sig.row.name == "old"
    job = store.get_job("j1")
    assert job.owner == "local" and job.runner == "host:123:abcd" and job.fraction == 0.5
    assert job.status == "running" and job.run_s == 0.0
    sweep, _ = store.get_sweep("j1", scope="local")
    assert sweep.name == "sw"
    assert store.get_sweep("j1", scope="someone") is None
    store.migrate()  # idempotent
    store.dispose()


def test_first_revision_is_the_schema_before_migrations(tmp_path) -> None:  # noqa: ANN001
    """Revision 0001 creates the four tables of the service as they were before migrations."""
    engine = make_engine(f"sqlite:///{tmp_path / 'first.db'}")
    migrations.upgrade(engine, migrations.FIRST)
    names = set(inspect(engine).get_table_names()) - {"alembic_version"}
    assert names == {"signals", "jobs", "sweeps", "workers"}
    cols = {c["name"] for c in inspect(engine).get_columns("jobs")}
    assert "owner" in cols and "runner" not in cols
    engine.dispose()


@pytest.mark.parametrize("step", ["0001", "0002"])
def test_downgrade_then_upgrade(tmp_path, step) -> None:  # noqa: ANN001
    from alembic import command

    engine = make_engine(f"sqlite:///{tmp_path / f'd{step}.db'}")
    migrations.upgrade(engine)
    with engine.begin() as conn:
        cfg = migrations.config()
        cfg.attributes["connection"] = conn
        command.downgrade(cfg, step)
    assert migrations.current(engine) == step
    assert migrations.upgrade(engine) == migrations.head()
    engine.dispose()
