"""SDK exceptions, mapped from the server's RFC 9457 problem documents."""

from __future__ import annotations

from typing import Any

from service.schemas import Job, Problem


class SnapwarnError(Exception):
    """Base of every error the SDK raises."""


class ApiError(SnapwarnError):
    """The server answered with a problem document (``.problem``; ``.status``)."""

    def __init__(self, problem: Problem, *, method: str = "", url: str = "") -> None:
        self.problem = problem
        self.status = problem.status
        self.method = method
        self.url = url
        msg = f"{problem.status} {problem.title}"
        if problem.detail:
            msg += f": {problem.detail}"
        super().__init__(msg)

    @property
    def field(self) -> str | None:
        """The first offending field, if the server named one."""
        return self.problem.errors[0].field if self.problem.errors else None

    @property
    def value(self) -> Any:
        """The first offending value, as the server echoed it."""
        return self.problem.errors[0].value if self.problem.errors else None


class BadRequest(ApiError):
    """400."""


class Unauthorized(ApiError):
    """401: missing or wrong API key."""


class NotFound(ApiError):
    """404."""


class Conflict(ApiError):
    """409: e.g. a chart of a sweep that has not succeeded yet."""


class PayloadTooLarge(ApiError):
    """413: over the server's limits."""


class UnsupportedMediaType(ApiError):
    """415: unknown file format."""


class InvalidInput(ApiError):
    """422: the field and the value are in ``.field`` / ``.value`` / ``.problem.errors``."""


class NotImplementedOnServer(ApiError):
    """501: the numerics this resource needs are not installed on the server."""


class ServerError(ApiError):
    """5xx."""


class TransportFailed(SnapwarnError):
    """No answer from the server: connection refused, timeout, broken protocol.

    The transport's own exception (``httpx2.TransportError``) is kept as ``__cause__``.
    """


class JobFailed(SnapwarnError):
    """A job ended as failed; ``.job.error`` says why."""

    def __init__(self, job: Job) -> None:
        self.job = job
        err = job.error
        why = f"{err.title}: {err.detail}" if err else "no reason given"
        super().__init__(f"job {job.id} ({job.kind}) failed: {why}")


class WaitTimeout(SnapwarnError):
    """``wait`` gave up before the job ended."""


_BY_STATUS: dict[int, type[ApiError]] = {
    400: BadRequest,
    401: Unauthorized,
    404: NotFound,
    409: Conflict,
    413: PayloadTooLarge,
    415: UnsupportedMediaType,
    422: InvalidInput,
    501: NotImplementedOnServer,
}


def error_for(problem: Problem, *, method: str = "", url: str = "") -> ApiError:
    cls = _BY_STATUS.get(problem.status)
    if cls is None:
        cls = ServerError if problem.status >= 500 else ApiError
    return cls(problem, method=method, url=url)
