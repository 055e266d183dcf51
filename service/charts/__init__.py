"""Charts of snapwarn's results, drawn by matplotlib (Agg) and shared by the API's pages and
routes and by the CLI's ``--plot``. Every axis carries the user's control name and unit and the
records' time unit; nothing here computes physics, only what the results hold.
"""

from service.charts._base import FORMATS, MEDIA, NONDIM, format_of, label, to_bytes, write
from service.charts.detection import (
    fit_chart,
    fit_figure,
    model_curve,
    spectrum_figure,
)
from service.charts.sweep import SweepSeries, sweep_chart, sweep_figure

__all__ = [
    "FORMATS",
    "MEDIA",
    "NONDIM",
    "SweepSeries",
    "fit_chart",
    "fit_figure",
    "format_of",
    "label",
    "model_curve",
    "spectrum_figure",
    "sweep_chart",
    "sweep_figure",
    "to_bytes",
    "write",
]
