"""The leading growth rate with an error estimate it measures itself (docs/spectrum.md §5).

The eigenvalue s of a pulse is computed on the pulse's own grid (level 0) and on its nested
refinements (level k: the grid of level k − 1 with the midpoints inserted, N → 2N − 1, the steady
equations re-solved by Newton on it, :func:`slippulse.steady.solver.refine_nested`). The discrete
eigenvalue converges smoothly under nested refinement (unlike on re-adapted grids), but near τ_min
not yet monotonically at the sizes this machine affords (docs/spectrum.md §5), so the estimate is
the plain one that needs no assumed order:

    s = s_K (the finest level),   s_err = |s_K − s_{K−1}|,

i.e. the last correction is taken as the size of the remaining error. With three levels or more
the observed order is reported as well (log₂ of the ratio of the last two corrections, where they
have one sign); it is not used to shrink the error bar.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..core.errors import UsageError
from ..steady import solver
from .spectrum import order4_pulse, pulse_spectrum  # noqa: F401 (order4_pulse: re-exported)

#: The error estimate needs a nested level of at least this many points below it (and the
#: finest level must fit the dense solver, :data:`slippulse.steady.solver.MAX_POINTS`).
MIN_REFINE_POINTS = 200


@dataclass
class RefinedRate:
    """The leading eigenvalue with its measured uncertainty (1/s), and the levels it came from."""

    s: float                         # Re σ of the finest level, 1/s
    s_err: float                     # |s_K − s_{K−1}|, 1/s
    rate_unit: float                 # c_p/L of the finest level, 1/s
    n_points: list = field(default_factory=list)
    s_levels: list = field(default_factory=list)        # Re σ per level, 1/s
    imag_levels: list = field(default_factory=list)     # Im σ per level, 1/s
    translation_levels: list = field(default_factory=list)   # σ_t per level, 1/s
    order: float = float("nan")      # observed order from the last three levels (nan if < 3)
    status: str = "converged"
    message: str = ""
    wall_time: float = 0.0

    @property
    def sign_resolved(self) -> bool:
        """|s| ≥ 2 s_err: the sign of s is beyond its uncertainty."""
        return bool(abs(self.s) >= 2.0 * self.s_err)

    def per_length(self):
        """(s L/c_p, s_err L/c_p)."""
        return self.s / self.rate_unit, self.s_err / self.rate_unit

    def describe(self) -> str:
        """'s L/c_p = 0.656 ± 0.054' or 'sign not resolved (s L/c_p in [a, b])'."""
        s, e = self.per_length()
        if self.status != "converged":
            return f"refinement failed: {self.message}"
        if not self.sign_resolved:
            return f"sign not resolved (s L/c_p in [{s - e:.2g}, {s + e:.2g}], |s| < 2 s_err)"
        return f"s L/c_p = {s:.4g} ± {e:.1g}"


def check_refinable(pulse, levels):
    """Refuse a pulse whose grid cannot carry the nested levels (too coarse, or too large)."""
    n = int(pulse.n_points)
    if n < MIN_REFINE_POINTS:
        raise UsageError(f"pulse {pulse.label}: N = {n} is too coarse to refine; the error "
                         f"estimate needs N >= {MIN_REFINE_POINTS} (re-solve with more --points)")
    finest = n
    for _ in range(levels):
        finest = 2 * finest - 1
    if finest > solver.MAX_POINTS:
        raise UsageError(f"pulse {pulse.label}: N = {n} refined {levels} time(s) is {finest} > "
                         f"{solver.MAX_POINTS} points (dense solver); use --levels "
                         f"{max(levels - 1, 1)} or a coarser pulse")


def refine_leading(pulse, params, first, levels=1, tol=1e-7, progress=None):
    """The leading eigenvalue on `levels` nested refinements of the pulse's grid.

    Parameters
    ----------
    pulse : Pulse (order 4)
    first : PulseSpectrum of the pulse on its own grid (level 0), with its leading mode.
    levels : number of nested refinements (≥ 1).
    progress : callable(str) or None, told about each level.

    Returns
    -------
    RefinedRate; status 'failed' (and no number) when a steady re-solve or an eigen-solve fails.
    """
    t0 = time.perf_counter()
    lead = first.leading
    out = RefinedRate(float("nan"), float("nan"), first.rate_unit, [int(first.n_points)],
                      [lead.real], [lead.imag], [float(first.neutral[1].real)])
    p = pulse
    mode = first.modes[0]["V"] if first.modes else None
    for lev in range(1, levels + 1):
        sol = solver.refine_nested(params, p)
        if not sol.stats.converged:
            out.status = "failed"
            out.message = (f"steady Newton on nested level {lev} (N = {sol.problem.n}) did not "
                           f"converge: {sol.stats.message}")
            break
        q = sol.to_pulse()
        guess = lead * (q.c_p / q.L) / (p.c_p / p.L)
        gmode = None
        if mode is not None:               # the coarse mode, interpolated to the refined grid
            gmode = [np.interp(q.xi, p.xi, mode.real) + 1j * np.interp(q.xi, p.xi, mode.imag)]
        res = pulse_spectrum(q, params, guesses=[guess], extra=False, tol=tol, guess_modes=gmode)
        if res.status != "converged" or res.sigmas.size == 0:
            out.status = "failed"
            out.message = f"eigen-solve on nested level {lev} (N = {q.n_points}): {res.message}"
            break
        lead = res.leading
        mode = res.modes[0]["V"]
        p = q
        out.n_points.append(int(q.n_points))
        out.s_levels.append(lead.real)
        out.imag_levels.append(lead.imag)
        out.translation_levels.append(float(res.neutral[1].real))
        out.rate_unit = res.rate_unit
        if progress:
            progress(f"level {lev}: N={q.n_points} s L/c={lead.real / res.rate_unit:.5g}")
    if out.status == "converged":
        s = out.s_levels
        out.s = s[-1]
        out.s_err = abs(s[-1] - s[-2])
        if len(s) >= 3:
            d1, d2 = s[-2] - s[-3], s[-1] - s[-2]
            if d1 * d2 > 0 and d2 != 0:
                out.order = float(np.log2(abs(d1 / d2)))
        out.message = (f"{len(s)} levels, N = {'/'.join(str(n) for n in out.n_points)}")
    out.wall_time = time.perf_counter() - t0
    return out
