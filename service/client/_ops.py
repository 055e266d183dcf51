"""SDK methods written once for both clients: each is a *flow* (:data:`service.client._core.Flow`),
a generator that yields what to do (a ``Call`` to send, or a ``Sleep``) and receives the
answer; a client turns it into a method with its own transport.

>>> class Api(Operations):                                     # doctest: +SKIP
...     @operation
...     def get_job(self, job_id: str) -> Flow[Job]:
...         \"\"\"``GET /v1/jobs/{id}``.\"\"\"
...         return (yield core.get_job(job_id))

A subclass with ``_is_async = False`` gets ``get_job(job_id) -> Job`` (sent with its ``_run``,
waits with ``time.sleep``); one with ``_is_async = True`` gets ``async def get_job(job_id) ->
Job`` (awaits its ``_run``, ``asyncio.sleep``). Both keep the flow's name, docstring and
signature (the return annotation without ``Flow[...]``), so ``help()``, ``inspect`` and IDEs
see ordinary methods; an exception from sending is thrown into the flow, whose ``finally``
blocks run as in a plain method.
"""

from __future__ import annotations

import asyncio
import functools
import inspect
import re
import time
from collections.abc import Awaitable, Callable, Coroutine
from typing import (
    Any,
    ClassVar,
    Concatenate,
    Generic,
    Literal,
    ParamSpec,
    Protocol,
    TypeVar,
    overload,
)

from service.client._core import Call, Flow, Sleep

__all__ = ["Operations", "drive", "drive_async", "operation"]

P = ParamSpec("P")
R = TypeVar("R")


class _Steps:
    """A flow as a driver steps it: ``next`` is what to do, None once it has returned
    ``value``."""

    def __init__(self, flow: Flow[Any]) -> None:
        self.flow = flow
        self.value: Any = None
        self.next: Call | Sleep | None = self._go(flow.send, None)

    def _go(self, how: Callable[[Any], Any], arg: Any) -> Any:
        try:
            return how(arg)
        except StopIteration as stop:
            self.value = stop.value
            return None

    def answer(self, value: Any) -> None:
        """The answer to ``next`` (None after a pause) goes into the flow."""
        self.next = self._go(self.flow.send, value)

    def fail(self, exc: Exception) -> None:
        """``next`` failed: the error is raised in the flow (its ``finally`` blocks run)."""
        self.next = self._go(self.flow.throw, exc)


def _pause(seconds: float) -> Any:
    """A pause of a blocking flow (it answers None)."""
    time.sleep(seconds)


async def _apause(seconds: float) -> Any:
    """A pause of an asyncio flow (it answers None)."""
    await asyncio.sleep(seconds)


def drive(run: Callable[[Call], Any], flow: Flow[R]) -> R:
    """Run ``flow`` to its end with a blocking transport ``run`` (a client's ``_run``)."""
    s = _Steps(flow)
    while (step := s.next) is not None:
        try:
            answer = _pause(step.seconds) if isinstance(step, Sleep) else run(step)
        except Exception as exc:  # noqa: BLE001 - the flow decides
            s.fail(exc)
        else:
            s.answer(answer)
    return s.value


async def drive_async(run: Callable[[Call], Awaitable[Any]], flow: Flow[R]) -> R:
    """Run ``flow`` to its end with an asyncio transport ``run``."""
    s = _Steps(flow)
    while (step := s.next) is not None:
        try:
            answer = await (_apause(step.seconds) if isinstance(step, Sleep) else run(step))
        except Exception as exc:  # noqa: BLE001 - the flow decides
            s.fail(exc)
        else:
            s.answer(answer)
    return s.value


class _SyncClient(Protocol):
    _is_async: ClassVar[Literal[False]]


class _AsyncClient(Protocol):
    _is_async: ClassVar[Literal[True]]


_FLOW_RETURN = re.compile(r"^Flow\[(.*)\]$")


class operation(Generic[P, R]):  # noqa: N801 - used as a decorator
    """A method declared once as a flow; :class:`Operations` makes it a real method of each
    client (a coroutine function for an asyncio client)."""

    def __init__(self, flow: Callable[Concatenate[Any, P], Flow[R]]) -> None:
        self.flow = flow
        functools.update_wrapper(self, flow)  # type: ignore[arg-type]

    def method(self, is_async: bool, module: str, qualname: str) -> Callable[..., Any]:
        """The client method: ``flow`` driven by the client's ``_run``."""
        flow = self.flow

        async def coroutine(self: Any, /, *args: Any, **kwargs: Any) -> Any:
            return await drive_async(self._run, flow(self, *args, **kwargs))

        def blocking(self: Any, /, *args: Any, **kwargs: Any) -> Any:
            return drive(self._run, flow(self, *args, **kwargs))

        method: Any = coroutine if is_async else blocking

        sig = inspect.signature(flow)
        ret = sig.return_annotation
        if isinstance(ret, str) and (m := _FLOW_RETURN.match(ret)):
            ret = m.group(1)
        method.__name__, method.__qualname__ = flow.__name__, qualname
        method.__doc__, method.__module__ = flow.__doc__, module
        method.__signature__ = sig.replace(return_annotation=ret)  # type: ignore[attr-defined]
        method.__annotations__ = {**flow.__annotations__, "return": ret}
        method.__wrapped_flow__ = flow  # type: ignore[attr-defined]
        return method

    # what a type checker sees (at run time each client holds a real method instead)
    @overload
    def __get__(self, obj: None, owner: type) -> operation[P, R]: ...
    @overload
    def __get__(self, obj: _AsyncClient, owner: type) -> Callable[P, Coroutine[Any, Any, R]]: ...
    @overload
    def __get__(self, obj: _SyncClient, owner: type) -> Callable[P, R]: ...
    def __get__(self, obj: Any, owner: type) -> Any:
        if obj is None:
            return self
        fn = self.method(bool(getattr(obj, "_is_async", False)), owner.__module__,
                         f"{owner.__qualname__}.{self.flow.__name__}")  # fmt: skip
        return fn.__get__(obj)


class Operations:
    """Base of the clients: a concrete client (a subclass that sets ``_is_async`` itself) gets,
    for every :class:`operation` of its classes, a real method driven by its own ``_run``."""

    _is_async: ClassVar[bool] = False

    def __init_subclass__(cls, **kw: Any) -> None:
        super().__init_subclass__(**kw)
        if "_is_async" not in vars(cls):
            return  # a class of declarations (mixed into the clients)
        for klass in reversed(cls.__mro__):
            for name, value in vars(klass).items():
                if isinstance(value, operation) and inspect.getattr_static(cls, name) is value:
                    method = value.method(cls._is_async, klass.__module__,
                                          f"{cls.__qualname__}.{name}")  # fmt: skip
                    setattr(cls, name, method)
