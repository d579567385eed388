"""Checks the commands make on their options before any work: finite numbers, figure formats,
writable outputs. Each failure is a :class:`~slippulse.core.errors.UsageError` naming the option
(one line, exit code 2). :func:`plural` words the counts of the summary lines."""
from __future__ import annotations

import math
import os

from ..core.errors import UsageError
from ..core.h5io import check_writable


def finite(value: float, option: str, lo: float | None = None, hi: float | None = None,
           lo_open: bool = True, unit: str = "") -> float:
    """``value`` if it is finite and within (lo, hi] (``lo_open``) or [lo, hi]; else a
    UsageError naming ``option`` (e.g. ``"--step"``) and the valid range."""
    rng = (f"{'(' if lo_open else '['}{'-inf' if lo is None else f'{lo:g}'}, "
           f"{'inf' if hi is None else f'{hi:g}'}]")
    ok = isinstance(value, (int, float)) and math.isfinite(value)
    if ok and lo is not None:
        ok = value > lo if lo_open else value >= lo
    if ok and hi is not None:
        ok = value <= hi
    if not ok:
        raise UsageError(f"{option}={value!r} is invalid: must be a finite number in {rng}"
                         + (f" {unit}" if unit else ""))
    return float(value)


def check_labels(path: str, labels, option: str = "--labels") -> list[str]:
    """The pulse labels of the file ``path``; a UsageError naming ``option``, the labels of
    ``labels`` that the file lacks and those it has, where any is missing."""
    from ..core.h5io import list_pulses
    have = list_pulses(path)
    missing = [lab for lab in labels if lab not in have]
    if missing:
        raise UsageError(f"{option}={missing} is invalid: not in {path!r} (labels "
                         f"{', '.join(have[:6])}{' ...' if len(have) > 6 else ''})")
    return have


def check_distinct(out: str, option: str, **inputs) -> None:
    """Refuse an output that is one of the command's input files (``inputs``: option name →
    path), before any work: writing it would destroy the input (--overwrite included)."""
    for name, path in inputs.items():
        if not path or not os.path.exists(path) or not os.path.exists(out):
            same = bool(path) and os.path.realpath(out) == os.path.realpath(path)
        else:
            same = os.path.samefile(out, path)
        if same:
            raise UsageError(f"{option}={out!r} is also the input {name}; give another output "
                             "file (the input would be overwritten)")


#: Valid range of the steady solver's residual target max|Δ| (relative to τ_d): a target above it
#: would accept a starting guess as a pulse (max|Δ| of a default guess is ~1); below 1e-16 it is
#: under the round-off of the residual itself.
TOL_RANGE = (1e-16, 1e-4)


def check_tol(value: float, option: str = "--tol") -> float:
    """``value`` if it is within :data:`TOL_RANGE`; else a UsageError naming the option."""
    lo, hi = TOL_RANGE
    if not (isinstance(value, (int, float)) and math.isfinite(value) and lo <= value <= hi):
        raise UsageError(f"{option}={value!r} is invalid: must be a number in [{lo:g}, {hi:g}] "
                         "(the max |residual| a converged pulse must reach; a larger target would "
                         "accept an unconverged guess)")
    return float(value)


def figure_formats() -> set[str]:
    """File extensions matplotlib can write (png, pdf, svg, ...)."""
    from matplotlib.backend_bases import FigureCanvasBase
    return set(FigureCanvasBase.get_supported_filetypes())


def check_figure(path: str, option: str) -> None:
    """Refuse a figure path whose extension matplotlib cannot write, or that cannot be written."""
    ext = os.path.splitext(path)[1].lstrip(".").lower()
    formats = figure_formats()
    if ext not in formats:
        raise UsageError(f"{option}={path!r}: unsupported figure format {ext or '(none)'!r}; "
                         f"use one of {', '.join(sorted(formats))}")
    check_writable(path, option)


def check_outdir(path: str, option: str) -> None:
    """Refuse an output directory that is a file or in which no file can be created."""
    if os.path.exists(path) and not os.path.isdir(path):
        raise UsageError(f"{option}={path!r} is a file, not a directory")
    check_writable(os.path.join(path, "probe.tmp"), option)


def plural(n: int, word: str) -> str:
    """'1 pulse', '3 pulses'."""
    return f"{n} {word}" + ("" if n == 1 else "s")
