"""Service settings: environment variables ``SNAPWARN_*`` (pydantic-settings)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

DEFAULT_DB_URL = "sqlite:///./var/snapwarn.db"


def _default_workers() -> int:
    return max(1, min(4, os.cpu_count() or 1))


class Settings(BaseSettings):
    """Everything the service can be told; each field is also ``SNAPWARN_<FIELD>`` in the env.

    Example: ``SNAPWARN_DB_URL=postgresql+psycopg://user@host/db snapwarn serve``.
    """

    model_config = SettingsConfigDict(env_prefix="SNAPWARN_", extra="ignore")

    db_url: str = Field(
        default=DEFAULT_DB_URL,
        description="SQLAlchemy URL: SQLite file (default) or postgresql+psycopg://...",
    )
    host: str = "127.0.0.1"
    port: int = Field(default=8000, ge=0, le=65535)
    http_workers: int = Field(default=1, ge=1, description="uvicorn worker processes.")
    log_level: str = "info"
    http_impl: Literal["auto", "httptools", "h11"] = Field(
        default="auto",
        description="uvicorn HTTP parser: 'auto' (httptools if installed), 'httptools' or 'h11'.",
    )
    loop_impl: Literal["auto", "uvloop", "asyncio"] = Field(
        default="auto",
        description="uvicorn event loop: 'auto' (uvloop if installed), 'uvloop' or 'asyncio'.",
    )
    forwarded_allow_ips: list[str] = Field(
        default_factory=list,
        description="Addresses of reverse proxies whose X-Forwarded-For/-Proto are trusted (the "
        "access log then shows the client's address); none by default: no request's "
        "forwarding headers are read (the API does not use the client's address).",
    )
    api_key: str | None = Field(
        default=None,
        description="A single admin key from the environment (compared in constant time); "
        "keys made with `snapwarn keys create` are stored hashed in the database.",
    )
    auth: Literal["auto", "on", "off"] = Field(
        default="auto",
        description="API keys on /v1: 'auto' requires them when the server listens beyond "
        "loopback, 'on' always, 'off' never (explicit opt-out).",
    )
    cors_origins: list[str] = Field(
        default_factory=list,
        description="Origins allowed to call the API from a browser (CORS); none by default.",
    )
    allowed_hosts: list[str] = Field(
        default_factory=list,
        description="Host names a request may name to reach a loopback server without keys "
        "(besides localhost and loopback addresses; any other Host is refused: DNS-rebinding "
        "defence).",
    )

    hot_path: bool = Field(
        default=True,
        description="POST /v1/detections with a small inline body answered by a middleware "
        "before the framework's routing (the same worker function, documents and errors).",
    )

    # Limits (413 beyond them).
    max_body_bytes: int = Field(default=64 * 1024 * 1024, ge=1024)
    max_samples: int = Field(default=4_000_000, ge=2)
    max_sweep_signals: int = Field(default=500, ge=2)
    max_prediction_points: int = Field(
        default=10_000,
        ge=3,
        description="Most points (rows) of a table sent to POST /v1/predictions (422 beyond; "
        "the prediction's cost grows with them: about 4 s for 10 000 points).",
    )
    min_sweep_signals: int = Field(
        default=3, ge=3, description="Fewest recorded signals a sweep needs (the pipeline's)."
    )
    max_decompressed_bytes: int = Field(
        default=256 * 1024 * 1024,
        ge=1024,
        description="Largest uncompressed size of the arrays in an NPZ/MAT upload (zip bombs).",
    )
    max_json_depth: int = Field(default=32, ge=2, description="Deepest nesting of metadata.")
    json_stream_bytes: int = Field(
        default=1 << 20,
        ge=0,
        description="JSON bodies larger than this are parsed as they arrive, their sample "
        "arrays straight into float64 (bounded memory); smaller ones in one piece (faster).",
    )
    max_elements: int = Field(
        default=400,
        ge=4,
        description="Most rod elements of a scene (simulations, snaps, atlas cells), given or "
        "chosen from rtol.",
    )
    max_sim_duration: float = Field(
        default=500.0, gt=0, description="Longest simulated duration (time units)."
    )
    max_sim_work: float = Field(
        default=25_000_000.0,
        gt=0,
        description="Largest work of a Cosserat-rod simulation in element-steps: its elements "
        "(given or chosen from rtol) x the time steps it will run (sim.resolution.rod_cost: "
        "the duration given or the default 40 fundamental periods, at ~3.6 / sqrt(rtol) steps "
        "per period, or one per sample where dt is finer). About 0.4 us of one core per "
        "element-step: the default is ~10 s (290 elements at the default rtol over ~44 time "
        "units; the default duration is 12 000 steps). The Euler beam and the normal form are "
        "not charged.",
    )
    max_active_jobs_per_owner: int = Field(
        default=16, ge=1, description="Queued + running jobs one owner may have (429 beyond)."
    )
    request_time_limit_s: float = Field(
        default=60.0,
        gt=0,
        description="Time limit of the work of one request (answered at once, not a job).",
    )
    job_time_limit_s: float = Field(
        default=1800.0, gt=0, description="Time limit of a job (failed with a reason beyond it)."
    )
    body_read_timeout_s: float = Field(
        default=30.0,
        gt=0,
        description="Longest wait for the next bytes of a request body (408 and the connection "
        "closed beyond): a slow client holds no worker for ever.",
    )
    header_read_timeout_s: float = Field(
        default=20.0,
        gt=0,
        description="Longest time a client may take to send a request's headers, from the "
        "connection (or the request's first byte) on: 408 and the connection closed beyond, or "
        "closed without an answer if nothing was sent (service.api.header_guard).",
    )
    max_header_bytes: int = Field(
        default=64 * 1024,
        gt=0,
        description="Most bytes of a request's line and headers: 431 and closed beyond.",
    )
    idempotency_lease_s: float = Field(
        default=10.0,
        gt=0,
        description="Lease of a claimed Idempotency-Key, renewed while its request runs: a key "
        "whose request died is recovered by a retry after it (409 with Retry-After before).",
    )
    uniform_rtol: float = Field(
        default=1e-3, gt=0, description="Max relative deviation of diff(t) from its mean."
    )

    # CPU-bound work.
    executor: str = Field(
        default="process", description="'process' (default) or 'thread' for the analysis pool."
    )
    analysis_workers: int = Field(default_factory=_default_workers, ge=1)
    warm_pool: bool = Field(default=True, description="Start and warm the pool at startup.")
    gil_switch_interval_s: float = Field(
        default=0.0005,
        gt=0,
        description="sys.setswitchinterval of the server process (hand-offs to the pool's "
        "threads wait up to this long).",
    )

    # Jobs.
    run_jobs: bool = Field(
        default=True, description="Run jobs in this server; false when `snapwarn worker` does."
    )
    job_workers: int = Field(default=1, ge=1, description="Jobs run concurrently per runner.")
    job_poll_s: float = Field(default=0.2, gt=0)
    job_heartbeat_s: float = Field(default=1.0, gt=0)
    job_lease_s: float = Field(
        default=15.0, gt=0, description="A running job silent this long is resumed elsewhere."
    )
    job_max_attempts: int = Field(
        default=5, ge=1, description="Starts of a job (restarts resume it) before it fails."
    )
    heartbeat_file: str | None = Field(
        default=None,
        description="A file the job runner touches at every heartbeat "
        "(for container healthchecks of `snapwarn worker`).",
    )
    sync_simulation_models: list[str] = Field(
        default_factory=lambda: ["normal-form", "euler-beam"],
        description="Models whose simulations answer at once; others become jobs.",
    )

    @field_validator("executor")
    @classmethod
    def _check_executor(cls, v: str) -> str:
        if v not in ("process", "thread"):
            raise ValueError(f"executor must be 'process' or 'thread', got {v!r}")
        return v

    def sqlite_path(self) -> Path | None:
        """The SQLite file of ``db_url`` (None for other databases or in-memory)."""
        prefix = "sqlite:///"
        if self.db_url.startswith(prefix):
            p = self.db_url[len(prefix) :]
            if p and p != ":memory:":
                return Path(p)
        return None
