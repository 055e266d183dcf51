"""Alembic migrations of the service database, shipped inside the package.

``upgrade(engine)`` brings any database to the head: an empty one is created by the first
migration, a database made before migrations existed (by ``create_all``, no
``alembic_version`` table) is stamped at the first revision and then upgraded, keeping its rows.
Command line: ``snapwarn db upgrade`` / ``snapwarn db current``, or ``alembic -c
service/api/migrations/alembic.ini upgrade head`` with ``SNAPWARN_DB_URL`` set.
"""

from __future__ import annotations

import time
from pathlib import Path

from sqlalchemy import Engine, inspect, text
from sqlalchemy.exc import IntegrityError, OperationalError, ProgrammingError

HERE = Path(__file__).resolve().parent
FIRST = "0001"


def config(engine_url: str | None = None):  # noqa: ANN201 - alembic.config.Config
    """An Alembic config pointing at these migrations (no ini file needed)."""
    from alembic.config import Config

    cfg = Config()
    cfg.set_main_option("script_location", str(HERE))
    if engine_url:
        cfg.set_main_option("sqlalchemy.url", engine_url.replace("%", "%%"))
    return cfg


def head() -> str:
    from alembic.script import ScriptDirectory

    return ScriptDirectory.from_config(config()).get_current_head() or FIRST


def current(engine: Engine) -> str | None:
    """The revision of the database (None for an empty or pre-migration database)."""
    with engine.connect() as c:
        if not inspect(c).has_table("alembic_version"):
            return None
        return c.execute(text("SELECT version_num FROM alembic_version")).scalar()


def _upgrade_once(engine: Engine, target: str) -> None:
    from alembic import command

    with engine.begin() as conn:
        if conn.dialect.name == "postgresql":  # one process migrates, the others wait
            conn.execute(text("SELECT pg_advisory_xact_lock(715517)"))
        cfg = config()
        cfg.attributes["connection"] = conn
        insp = inspect(conn)
        if not insp.has_table("alembic_version") and insp.has_table("jobs"):
            command.stamp(cfg, FIRST)  # made by create_all before migrations existed
        command.upgrade(cfg, target)


def upgrade(engine: Engine, target: str = "head") -> str | None:
    """Upgrade the database of ``engine`` to ``target``; returns the revision reached."""
    if target == "head" and current(engine) == head():
        return head()
    for attempt in range(6):
        try:
            _upgrade_once(engine, target)
            break
        except (IntegrityError, ProgrammingError, OperationalError):
            if attempt == 5:
                raise
            time.sleep(0.2 * (attempt + 1))  # another process migrated meanwhile
    return current(engine)
