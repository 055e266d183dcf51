"""Alembic environment: the connection comes from ``upgrade()`` or from ``sqlalchemy.url`` /
``SNAPWARN_DB_URL``; the target metadata is every table of ``service.api.storage``."""

from __future__ import annotations

import importlib
import os
import pkgutil

from alembic import context
from sqlalchemy import create_engine

import service.api.storage as storage
from service.api.storage import Base

for _info in pkgutil.iter_modules(storage.__path__):
    importlib.import_module(f"service.api.storage.{_info.name}")

config = context.config
target_metadata = Base.metadata


def _run(connection) -> None:  # noqa: ANN001
    context.configure(
        connection=connection,
        target_metadata=target_metadata,
        render_as_batch=connection.dialect.name == "sqlite",
    )
    with context.begin_transaction():
        context.run_migrations()


conn = config.attributes.get("connection")
if conn is not None:
    _run(conn)
else:
    url = config.get_main_option("sqlalchemy.url") or os.environ.get(
        "SNAPWARN_DB_URL", "sqlite:///./var/snapwarn.db"
    )
    if context.is_offline_mode():
        context.configure(url=url, target_metadata=target_metadata, literal_binds=True)
        with context.begin_transaction():
            context.run_migrations()
    else:
        engine = create_engine(url)
        with engine.begin() as c:
            _run(c)
        engine.dispose()
