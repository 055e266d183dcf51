"""Recorded signals in: one reader, one set of rules, for the CLI and the REST API.

A recording is a record of the probe's position ``w`` sampled on a uniform time grid. Labs
write it in many layouts; this module reads them all into one :class:`Recording` and refuses
what it cannot read without guessing, with a :class:`RecordingError` that names the field and
echoes the value. It knows neither HTTP nor the command line: the API maps the errors to
problem documents (415 for :class:`UnsupportedFormat`, 413 for :class:`RecordingTooLarge`, 422
otherwise), the CLI to its one-line error.

Layouts
-------
CSV (``,``, ``;``, tab or blanks) with a header row
    Text in UTF-8 (with or without a BOM), UTF-16 with its BOM (a spreadsheet's "Unicode
    text"), else Windows-1252 (``metadata["encoding"]`` says which); ``#`` comment lines and
    blank lines are skipped, and errors name the line as a text editor numbers it.
    The time column is recognised by its name (``t``, ``time``, ``timestamp``, ``seconds``...),
    with its unit kept from the header: ``t [ms]``, ``time (s)``, ``time_s``, or from a row of
    units under the header (``s,mm`` or ``(ms),(V)``, as oscilloscopes write). The signal is the
    one other column (any name, e.g. ``accel_mV`` or ``w [mm]``), or among several the one with
    a signal's name (``w``, ``x``, ``signal``, ``displacement``...), or the one named by
    ``column``. A header that does not say which column is which is an error that lists the
    columns found, never a guess. A file without a time column needs ``dt``.
NPY
    1-D: the samples (give ``dt``). 2-D, two columns (or two rows): ``t`` then ``w``.
NPZ, MATLAB .mat
    Variables named as the CSV's columns (any case): the signal ``w`` (or ``signal``, ``x``,
    ``displacement``, ``data``...; or the one array besides the time), the time ``t`` (or
    ``time``, ``timestamps``...) or the step ``dt`` (or a sample rate ``fs``, ``Fs``,
    ``sample_rate``: ``dt = 1/fs``). An NPZ holding one unnamed (n, 2) array is read as a 2-D
    NPY.
WAV
    ``dt = 1 / rate``; ``channel`` picks one channel of a multi-channel file.

Sampling
--------
Explicit times must increase strictly and be uniform. Timestamps written with a limited number
of significant digits (``%.9g``, ``%.6g``, a logger's fixed decimals) jitter by the rounding of
the written values: that is not non-uniform sampling. When the steps deviate from their mean by
more than the tolerance ``uniform_rtol`` (one setting, ``SNAPWARN_UNIFORM_RTOL``, default
1e-3, honoured by the CLI and the API alike), each deviating step is compared with the rounding
of its two written timestamps (half a unit in their last written digit): if the rounding
explains it, ``dt`` and ``t0`` are the least-squares line through the timestamps and the
recording carries the flag ``rounded_timestamps`` that says so. Steps the rounding cannot
explain (a dropped sample, a jittering clock) are an error naming the worst step, unless
``resample=True``, which interpolates the record linearly onto a uniform grid (flag
``resampled``).

Saturation
----------
A record whose maximum or minimum is held in several separate runs (a sensor or converter at
the end of its range flattens every clipped peak) carries the flag ``clipped``.

Tables
------
:func:`read_table` reads a table of numbers (a sweep, a manifest of records) by the CSV's text
rules, with each column's unit from the header.

``dt`` given by the caller supplies the step of a record that has no time of its own (1-D
NPY, a one-column CSV); given for a file that carries its own times (a time column, ``t`` or
``dt`` variables, a WAV rate), it is an error: the two could disagree, and silently preferring
one of them has turned an omega of 16 into 125.7.
"""

from __future__ import annotations

from service.recordings._errors import (
    RecordingError,
    RecordingTooLarge,
    UnsupportedFormat,
)
from service.recordings._formats import guess_format, read_bytes, read_file, split_unit
from service.recordings._record import (
    DEFAULT_UNIFORM_RTOL,
    FORMATS,
    UNIFORM_RTOL_ENV,
    Recording,
    check_finite,
    quantity_of,
    time_axis,
    to_csv,
    to_f64,
    to_npy,
    uniform_rtol_from_env,
)
from service.recordings._table import PATH_NAMES, Table, manifest_columns, read_table
from service.recordings._time_units import common_time_base, seconds_per
from service.recordings._validate import from_arrays

__all__ = [
    "PATH_NAMES",
    "manifest_columns",
    "DEFAULT_UNIFORM_RTOL",
    "FORMATS",
    "UNIFORM_RTOL_ENV",
    "Recording",
    "RecordingError",
    "RecordingTooLarge",
    "Table",
    "UnsupportedFormat",
    "check_finite",
    "common_time_base",
    "from_arrays",
    "guess_format",
    "quantity_of",
    "read_bytes",
    "read_file",
    "read_table",
    "seconds_per",
    "split_unit",
    "time_axis",
    "to_csv",
    "to_f64",
    "to_npy",
    "uniform_rtol_from_env",
]
