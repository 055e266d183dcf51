"""``snapwarn watch DIR --control REGEX``: follow a folder a lab's logger writes records into.

Every new file whose name matches ``--control`` (a regular expression with one group, or a
group named ``control``, that captures the control value) is read when it stops changing, added
to a live sweep, and the updated warning is printed: one line per record, or one JSON document
per line with ``--json`` (the ``LiveUpdate`` wire model, as the API answers it). Files are
noticed by ``watchfiles`` (OS notifications), not by polling the folder.

Without ``--server`` the sweep runs in this process (:mod:`service.analysis.live`, the same
numerics as the service); with ``--server URL`` each file is uploaded to an open live sweep
there (``POST /v1/sweeps/{id}/records``), so dashboards can follow it. The watch ends after
``--budget`` records, after ``--idle`` seconds without a new record, or on Ctrl-C; a server's
sweep is then closed.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
import time
from pathlib import Path
from typing import Any

from service.cli._common import CliError, add_json_flag, bad, emit, error_from, finite

#: A file is read once its size and mtime have not changed for this long (s).
SETTLE_S = 0.3


def register(sub: Any) -> None:
    p = sub.add_parser(
        "watch",
        help="follow a folder of records: the warning after each new file",
        description=__doc__.split("\n\n")[1],
    )
    p.add_argument("dir", metavar="DIR", help="folder the logger writes records into")
    p.add_argument(
        "--control", required=True, metavar="REGEX",
        help="regular expression on the file name capturing the control value, e.g. "
        r"'mu_([-+0-9.eE]+)\.csv' (one group, or a group named 'control')",
    )  # fmt: skip
    p.add_argument("--server", metavar="URL", help="add the records to a live sweep there")
    p.add_argument("--api-key", default=os.environ.get("SNAPWARN_API_KEY"), help=argparse.SUPPRESS)
    p.add_argument("--name", help="the sweep's name (default: the folder's name)")
    p.add_argument("--control-name", default="mu", help="name of the control (default mu)")
    p.add_argument("--unit", help="unit of the control")
    p.add_argument("--step", type=finite, help="largest control step (control units)")
    p.add_argument("--margin", type=finite, default=0.0, help="kept below the bound on mu*")
    p.add_argument("--budget", type=int, help="stop after this many records")
    p.add_argument("--idle", type=finite, help="stop after this many seconds without a record")
    p.add_argument("--dt", type=finite, help="sample step of files without a time column")
    p.add_argument("--target-width", type=finite,
                   help="'converged' once the trusted interval is narrower (control units)")
    p.add_argument("--control-resolution", type=finite,
                   help="the finest control step the lab can set (control units)")
    from service.cli.analysis_cmds import _band, _lab_flags  # (the sweep's own flags)

    _lab_flags(p, start=False)
    p.add_argument("--band", type=_band, default=None, metavar="LO,HI",
                   help="the fundamental's band of sqrt|sigma2| (rad per time unit) in every "
                   "record (default: the mode that softens continuously across the sweep)")
    p.add_argument(
        "--skip-existing", action="store_true",
        help="ignore the matching files already in DIR (default: add them first, by control)",
    )  # fmt: skip
    add_json_flag(p)
    p.set_defaults(func=_watch)


# ------------------------------------------------------------------------------- the sources
def control_of(name: str, pattern: re.Pattern[str]) -> float | None:
    """The control value in a file name (None when the name does not match)."""
    m = pattern.search(name)
    if m is None:
        return None
    text = m.group("control") if "control" in pattern.groupindex else m.group(1)
    try:
        v = float(text)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


class InProcess:
    """The live sweep in this process: the numerics of the service, the same wire model."""

    def __init__(self, args: argparse.Namespace) -> None:
        from service.analysis.live import LivePlan

        self.plan = LivePlan(step=args.step, margin=args.margin, band=args.band,
                             target_width=args.target_width,
                             control_resolution=args.control_resolution)  # fmt: skip
        self.records: list[Any] = []
        self.dt = args.dt
        self.quantity, self.notch = args.quantity, args.notch

    def add(self, path: Path, control: float) -> Any:
        from service import convert
        from service.analysis.live import update, update_unreadable
        from service.analysis.sweep_policy import file_unreadable
        from service.recordings import RecordingError, read_file

        try:
            rec = read_file(path, dt=self.dt)
        except RecordingError as exc:  # set aside by its name, as a batch sweep does
            u = update_unreadable(self.records, control, file_unreadable(exc), plan=self.plan,
                                  name=path.name, time_unit=self._unit(None))  # fmt: skip
            self.records.append(u.record)
            return convert.live_update(u)
        dt, unit = rec.dt * self._factor(rec.unit), self._unit(rec.unit)
        # the record as the service's live door reads an uploaded file: named by its file,
        # the quantity its value unit says
        opts: dict[str, Any] = {}
        if self.quantity or rec.quantity:
            opts["quantity"] = self.quantity or rec.quantity
        if self.notch:
            opts["notch"] = list(self.notch)
        u = update(self.records, rec.w, dt=dt, control=control, plan=self.plan,
                   options=opts, name=path.name, time_unit=unit)  # fmt: skip
        self.records.append(u.record)
        return convert.live_update(u, options=opts)

    def time_unit(self) -> str | None:
        """The sweep's time unit (its first read record's; None before one)."""
        return self._unit(None)

    def _unit(self, unit: str | None) -> str | None:
        """The sweep's time unit: its first read record's (as the service's live door)."""
        from service.analysis.live import sweep_time_unit

        return sweep_time_unit(self.records, unit)

    def _factor(self, unit: str | None) -> float:
        """A record's step in the sweep's time unit (a file in ms after one in s is converted;
        unknown or missing units that differ are refused, as by the service)."""
        from service.recordings import seconds_per

        base = self._unit(unit)
        if unit == base:
            return 1.0
        a, b = seconds_per(unit), seconds_per(base)
        if a is None or b is None:
            raise bad("unit", unit, f"is not the time unit of the sweep's records "
                      f"({base or 'none given'}) and one of them is unknown")  # fmt: skip
        return a / b

    def close(self) -> None:
        pass


class Remote:
    """A live sweep on a server: each file is uploaded as it is."""

    def __init__(self, args: argparse.Namespace) -> None:
        from service.client import Client

        self.client = Client(args.server, api_key=args.api_key, timeout=300.0)
        opts = {k: v for k, v in (("step", args.step), ("margin", args.margin),
                                  ("budget", args.budget), ("band", args.band),
                                  ("notch", args.notch), ("target_width", args.target_width),
                                  ("control_resolution", args.control_resolution))
                if v is not None}  # fmt: skip
        self.live = self.client.live_sweep(
            args.name or Path(args.dir).resolve().name, control=args.control_name,
            unit=args.unit, **opts,
        )  # fmt: skip
        self.dt, self.quantity = args.dt, args.quantity
        self.seq = 0  # the last record's seq the watch has seen
        sys.stderr.write(f"live sweep {self.live.id} on {args.server}\n")

    def add(self, path: Path, control: float) -> Any:
        from service.client.errors import ApiError

        try:
            u = self.live.add(path, control=control, dt=self.dt, quantity=self.quantity)
        except ApiError as exc:
            # a file the server cannot read is refused (4xx) and kept in the sweep set aside
            # by its name: that record's update, as the in-process sweep prints it
            kept = [x for x in self.live.records(after=self.seq).items
                    if x.record_name == path.name and not x.used_in_fit]  # fmt: skip
            if not (400 <= exc.status < 500 and kept):
                raise
            sys.stderr.write(f"snapwarn watch: {path.name} set aside: {exc.problem.detail}\n")
            u = kept[-1]
        self.seq = max(self.seq, u.seq)
        return u

    def close(self) -> None:
        try:
            self.live.close()
        finally:
            self.client.close()


# ------------------------------------------------------------------------------- printing
def line(u: Any, name: str, unit: str | None = None, time_unit: str | None = None) -> str:
    """One human line: the record, its fundamental (``sigma2`` to its standard error, in Hz
    too when the record names its time unit), the type, mu* and its interval, the alarm, the
    next value (numbers written to the interval's precision, :mod:`service.numfmt`), control
    values with ``unit`` (the control's, ``--unit``); ``time_unit``: the sweep's (its first
    record's), when the detection does not name it."""
    from service import numfmt

    cu = f" {unit}" if unit else ""
    f = u.detection.fundamental
    parts = [f"#{u.seq} {name} control={u.control:.8g}{cu}"]
    if f is not None and f.sigma2 is not None:
        tu = u.detection.time_unit or time_unit
        s2 = f"sigma2={numfmt.fmt_pm(f.sigma2, f.sigma2_std)}" + (f" 1/{tu}^2" if tu else "")
        freq = numfmt.hz(f.omega, tu) if f.omega else None
        parts.append(s2 + (f" ({freq})" if freq else ""))
    else:
        parts.append("no mode")
    half = None
    if u.mu_star_interval and None not in u.mu_star_interval:
        half = 0.5 * (u.mu_star_interval[1] - u.mu_star_interval[0])
    if u.mu_star is not None:
        lo, hi = u.mu_star_interval or (None, None)
        p = u.probabilities.get(u.transition)
        pt = f" p={p:.2f}" if p is not None else ""
        a, b = numfmt.fmt_interval(lo, hi)
        parts.append(f"{u.transition}{pt} mu*={numfmt.fmt(u.mu_star, half)}{cu} [{a}, {b}]{cu}")
    parts.append(f"alarm={u.alarm.level}")
    if u.next_control is not None:
        nxt = numfmt.fmt_below(u.next_control, half, digits=8)
        parts.append(f"next<={nxt}{cu} ({u.next_bound_source})")
    else:
        parts.append("next: none")
    if u.converged:
        parts.append("converged")
    codes = list(dict.fromkeys(x.code for x in (*u.record_flags, *u.flags)))  # each once
    if codes:
        parts.append("flags=" + ",".join(codes))
    return " | ".join(parts)


def _g(v: float | None) -> str:
    return "?" if v is None else f"{v:.8g}"


# ------------------------------------------------------------------------------- the loop
class _Folder:
    """Files to add: noticed by watchfiles, read once settled, each once."""

    def __init__(self, root: Path, pattern: re.Pattern[str]) -> None:
        self.root, self.pattern = root, pattern
        self.pending: dict[Path, tuple[int, float, float]] = {}  # path -> size, mtime, seen
        self.done: set[Path] = set()

    def notice(self, path: Path) -> None:
        if path in self.done or control_of(path.name, self.pattern) is None:
            return
        try:
            st = path.stat()
        except OSError:
            return
        if not path.is_file():
            return
        prev = self.pending.get(path)
        if prev is None or (prev[0], prev[1]) != (st.st_size, st.st_mtime):
            self.pending[path] = (st.st_size, st.st_mtime, time.monotonic())

    def ready(self) -> list[Path]:
        now = time.monotonic()
        out = []
        for p, (size, mtime, seen) in list(self.pending.items()):
            try:
                st = p.stat()
            except OSError:
                del self.pending[p]
                continue
            if (st.st_size, st.st_mtime) != (size, mtime):
                self.pending[p] = (st.st_size, st.st_mtime, now)
            elif now - seen >= SETTLE_S and st.st_size > 0:
                out.append(p)
        out.sort(key=lambda p: (self.pending[p][2], p.name))
        return out


def _watch(args: argparse.Namespace) -> int:
    import watchfiles

    root = Path(args.dir)
    if not root.is_dir():
        raise bad("DIR", args.dir, "is not a folder")
    try:
        pattern = re.compile(args.control)
    except re.error as exc:
        raise bad("--control", args.control, f"is not a regular expression ({exc})") from None
    if pattern.groups < 1:
        raise bad("--control", args.control, "needs a group capturing the control value")
    if args.budget is not None and args.budget < 1:
        raise bad("--budget", args.budget, "must be >= 1")
    try:
        source: InProcess | Remote = Remote(args) if args.server else InProcess(args)
    except ValueError as exc:
        err = error_from(exc)
        raise err if err is not None else CliError(str(exc)) from None
    folder = _Folder(root, pattern)
    if not args.skip_existing:
        existing = sorted(
            (p for p in root.iterdir() if control_of(p.name, pattern) is not None),
            key=lambda p: (control_of(p.name, pattern), p.name),
        )
        for p in existing:
            folder.pending[p] = (-1, -1.0, 0.0)  # read at once, by control
    else:
        folder.done.update(p for p in root.iterdir())
    n = 0
    last_record = time.monotonic()
    try:
        with_watch = watchfiles.watch(
            root, rust_timeout=100, yield_on_timeout=True, debounce=50, step=20,
            raise_interrupt=False,
        )  # fmt: skip
        first = True
        for changes in _first_then(with_watch):
            if not first:
                for _, path in changes:
                    folder.notice(Path(path))
            first = False
            for p in _existing_first(folder):
                n += _add(source, p, folder, pattern, args)
                last_record = time.monotonic()
                if args.budget is not None and n >= args.budget:
                    return 0
            if args.idle is not None and time.monotonic() - last_record > args.idle:
                sys.stderr.write(f"no new record for {args.idle:g} s: stopping\n")
                return 0
    finally:
        source.close()
    return 0


def _first_then(it: Any) -> Any:
    yield set()  # the files found at the start, before any change
    yield from it


def _existing_first(folder: _Folder) -> list[Path]:
    first = [p for p, v in folder.pending.items() if v[0] == -1]
    if first:
        for p in first:
            del folder.pending[p]
        return first
    return folder.ready()


def _add(source: Any, p: Path, folder: _Folder, pattern: re.Pattern[str], args: Any) -> int:
    folder.pending.pop(p, None)
    folder.done.add(p)
    control = control_of(p.name, pattern)
    try:
        u = source.add(p, control)
    except Exception as exc:  # noqa: BLE001 - one bad file must not stop the watch
        err = error_from(exc, p.name) if isinstance(exc, ValueError) else None
        msg = str(err) if err is not None else f"{p.name}: {exc}"
        sys.stderr.write(f"snapwarn watch: skipped {msg}\n")
        return 0
    tu = source.time_unit() if isinstance(source, InProcess) else None
    emit(u, json_mode=args.json, text=line(u, p.name, args.unit, tu))
    sys.stdout.flush()
    return 1
