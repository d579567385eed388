"""The leading growth rate with an error estimate it measures itself (docs/spectrum.md §4).

The eigenvalue s of a pulse is computed on a ladder of grids sampled from one smooth map of the
pulse's grid (:class:`slippulse.steady.grid.GridMap`): level k has N_k = N_0 r^k points,
r = √2, and the steady equations re-solved by Newton on it. Grids of one smooth map give
discretisation errors that fall as a power of N (measured at 1.05 and 1.02 τ_min: order 3.8 and
4.3, docs/spectrum.md §4); nested refinement of the adapted grid, which keeps its spacing
jumps, did not (the sequence was not monotone).

The estimate (three levels or more; Roache's grid convergence index for three grids): with the
last two corrections d₁ = s_{K−1} − s_{K−2}, d₂ = s_K − s_{K−1} of one sign and |d₂| < |d₁|, the
observed order is p = ln(d₁/d₂)/ln r, and where 1 ≤ p ≤ 8

    s = s_K,   s_err = F_s |d₂| / (r^q − 1),   F_s = 1.25,   q = min(p, 4),

which covers the Richardson extrapolation s_K + d₂/(r^p − 1) with a margin; an observed order
above the scheme's formal order 4 (a level not yet in the asymptotic range, measured on deep
pulses: p = 7.5) is not trusted to shrink the band further. Otherwise (two
levels, corrections of opposite sign or growing, p outside [1, 8]) the plain estimate that
assumes no order:

    s = s_K,   s_err = |d₂|   (the last correction).

The same extrapolation is applied to the translation eigenvalue σ_t, whose exact value is 0
(:func:`richardson`): its extrapolated value, and whether its three-level error bar covers 0,
check the estimate against a known answer at every pulse (docs/spectrum.md §4).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from ..core.errors import UsageError
from ..steady import solver
from .pulse import NEWTON_TOL, order4_pulse, pulse_spectrum  # noqa: F401 (re-export)

#: The error estimate needs a pulse of at least this many points to map.
MIN_REFINE_POINTS = 200
#: Ratio of the point counts of consecutive levels.
LEVEL_RATIO = math.sqrt(2.0)
#: Factor of safety of the three-level estimate (grid convergence index, Roache 1998).
SAFETY = 1.25
#: Observed orders accepted by the three-level estimate.
ORDER_BOUNDS = (1.0, 8.0)
#: The formal order of the discretisation (state map, slip recursion, Hilbert operator): the band
#: of the three-level estimate uses no larger order than this.
FORMAL_ORDER = 4.0


def level_points(n0, levels):
    """Point counts of levels 0..levels: N_k = round(N_0 r^k), r = :data:`LEVEL_RATIO`."""
    return [int(round(n0 * LEVEL_RATIO ** k)) for k in range(int(levels) + 1)]


def estimate(s_levels, ratio=LEVEL_RATIO):
    """(s, s_err, order, rule) from the eigenvalue per level (see the module's docstring).

    rule is 'three-level' (order observed and used) or 'last correction'; order is nan when
    none is observed."""
    s = [float(x) for x in s_levels]
    if len(s) < 2:
        raise ValueError("an error estimate needs at least two levels")
    d2 = s[-1] - s[-2]
    if len(s) >= 3:
        d1 = s[-2] - s[-3]
        if d1 * d2 > 0 and abs(d2) < abs(d1):
            p = math.log(abs(d1 / d2)) / math.log(ratio)
            if ORDER_BOUNDS[0] <= p <= ORDER_BOUNDS[1]:
                q = min(p, FORMAL_ORDER)
                return s[-1], SAFETY * abs(d2) / (ratio ** q - 1.0), p, "three-level"
    return s[-1], abs(d2), float("nan"), "last correction"


def richardson(values, ratio=LEVEL_RATIO):
    """(extrapolated value, three-level error bar, order) of a sequence per level, where the
    three-level rule of :func:`estimate` applies: x_K + d₂/(r^p − 1) and F_s|d₂|/(r^p − 1);
    (nan, nan, nan) otherwise."""
    x = [float(v) for v in values]
    if len(x) < 3:
        return float("nan"), float("nan"), float("nan")
    val, err, p, rule = estimate(x, ratio)
    if rule != "three-level":
        return float("nan"), float("nan"), float("nan")
    return x[-1] + (x[-1] - x[-2]) / (ratio ** p - 1.0), err, p


@dataclass
class RefinedRate:
    """The leading eigenvalue with its measured uncertainty (1/s), and the levels it came from."""

    s: float                         # Re σ of the finest level, 1/s
    s_err: float                     # its uncertainty (module docstring), 1/s
    rate_unit: float                 # c_p/L of the finest level, 1/s
    n_points: list = field(default_factory=list)
    s_levels: list = field(default_factory=list)        # Re σ per level, 1/s
    imag_levels: list = field(default_factory=list)     # Im σ per level, 1/s
    translation_levels: list = field(default_factory=list)   # σ_t per level, 1/s (nan above
    #                                                  level 0 when pinned: not computed)
    order: float = float("nan")      # observed order from the last three levels (nan if none)
    rule: str = ""                   # 'three-level' or 'last correction'
    ratio: float = LEVEL_RATIO       # N_{k+1}/N_k
    target: float = float("nan")     # s_err L/c_p asked for (nan: fixed levels)
    target_met: bool = True
    status: str = "converged"
    message: str = ""
    wall_time: float = 0.0
    s_extrapolated: float = float("nan")            # Richardson value of s (nan: no order), 1/s
    translation_extrapolated: float = float("nan")  # the same for σ_t (exact 0), 1/s
    translation_err: float = float("nan")           # the three-level error bar of σ_t_K, 1/s
    pinned: bool = False             # translation pinned (σ_t = 0 by construction, no check)
    unit_levels: list = field(default_factory=list)     # c_p/L per level, 1/s
    s_per_L: float = float("nan")    # s L/c_p, estimated from its own levels (L converges too)
    s_err_per_L: float = float("nan")

    def add_level(self, n_points, res):
        """Append the leading eigenvalue of a level's spectrum `res` (on `n_points` points)."""
        lead = res.leading
        self.n_points.append(int(n_points))
        self.s_levels.append(lead.real)
        self.imag_levels.append(lead.imag)
        self.translation_levels.append(float(res.neutral[1].real))
        self.rate_unit = res.rate_unit
        self.unit_levels.append(res.rate_unit)

    @property
    def s_per_L_levels(self) -> list:
        """s_k L_k/c_k per level."""
        return [s / u for s, u in zip(self.s_levels, self.unit_levels)]

    @property
    def translation_covered(self) -> bool:
        """The error bar of the finest σ_t (exact 0), measured as that of s, covers 0 (False
        where no order was observed)."""
        return bool(abs(self.translation_levels[-1]) <= self.translation_err)

    @property
    def sign_resolved(self) -> bool:
        """|s| ≥ 2 s_err: the sign of s is beyond its uncertainty."""
        return bool(abs(self.s) >= 2.0 * self.s_err)

    def per_length(self):
        """(s L/c_p, s_err L/c_p): the estimate of the sequence s_k L_k/c_k, whose error holds
        that of L as well (at 1.2 τ_min, where s is converged to 1e−8, L's is the larger);
        s/(c_p/L) and s_err/(c_p/L) where the levels are not known."""
        if math.isfinite(self.s_per_L):
            return self.s_per_L, self.s_err_per_L
        return self.s / self.rate_unit, self.s_err / self.rate_unit

    def describe(self) -> str:
        """'s L/c_p = 0.6653 ± 0.0002' or 'sign not resolved (s L/c_p in [a, b])'."""
        s, e = self.per_length()
        if self.status != "converged":
            return f"refinement failed: {self.message}"
        if not self.sign_resolved:
            return f"sign not resolved (s L/c_p in [{s - e:.2g}, {s + e:.2g}], |s| < 2 s_err)"
        d = max(0, 1 - math.floor(math.log10(e))) if e > 0 else 6   # to the digit after e's
        return f"s L/c_p = {s:.{d}f} ± {e:.1g}"


def goal(target, rel_target, s_per_L):
    """The s_err L/c_p a ladder climbs to: max(target, rel_target |s L/c_p|)."""
    return max(float(target), float(rel_target) * abs(float(s_per_L)))


def level0_size(n, min_points=0, level0_points=None, max_points=None):
    """N_0 of level 0: exactly `level0_points` where given, else N clipped to
    [min_points, max_points] (max_points None: no upper bound)."""
    if level0_points:
        return int(level0_points)
    n0 = max(int(n), int(min_points))
    return min(n0, int(max_points)) if max_points else n0


def check_refinable(pulse, levels, min_points=0, level0_points=None, max_points=None):
    """Refuse a pulse whose grid cannot carry the levels (too coarse to map, or too large);
    level 0 has :func:`level0_size` points."""
    n = int(pulse.n_points)
    if n < MIN_REFINE_POINTS:
        raise UsageError(f"pulse {pulse.label}: N = {n} is too coarse to refine; the error "
                         f"estimate needs N >= {MIN_REFINE_POINTS} (re-solve with more --points)")
    n0 = level0_size(n, min_points, level0_points, max_points)
    finest = level_points(n0, levels)[-1]
    if finest > solver.MAX_POINTS:
        raise UsageError(f"pulse {pulse.label}: N = {n0} refined {levels} "
                         f"time(s) is {finest} > {solver.MAX_POINTS} points (dense solver); use "
                         f"fewer --levels or a smaller --min-points")


def mapped_pulse(params, pulse, gmap, n, tol=1e-13, creep=0):
    """The pulse re-solved (steady Newton, state order 4) on the grid ``gmap(n)``, started from
    its ln v interpolated there (creep > 0: give up once max|r| has not halved over `creep`
    iterations). Each full Newton step's LU is reused by chord iterations before a new Jacobian
    is formed (the start is close: measured on the deep pulses, 2 LUs instead of 4–5 at
    N = 3542–5009, BENCHMARKS.md), and the line search is Deuflhard's natural
    monotonicity test (the healing front, a few cm off on the finer grid, no longer cuts the
    steps: 15 → 3 LUs at L = 3.8 km, N = 5009); where that fails, the re-solve is made
    again with the ‖r‖₂ line search (at 6.70 km, N = 3542, the natural test stopped at max|r| =
    1.2e−5 after 31 iterations, where the ‖r‖₂ test converges). The tolerance is the
    same. Returns a :class:`slippulse.steady.solver.SteadySolution`."""
    sol = solver.resolve_on_grid(params, pulse, gmap(n), tol=tol, state_order=4, creep=creep,
                                 reuse=True, line_search="natural")
    if sol.stats.converged:
        return sol
    alt = solver.resolve_on_grid(params, pulse, gmap(n), tol=tol, state_order=4, creep=creep,
                                 reuse=True)
    if not alt.stats.converged:
        alt.stats.message = (f"{alt.stats.message} (and with the natural line search: "
                             f"{sol.stats.message})")
    return alt


#: Largest level of a ladder that climbs toward a target (dense complex N×N matrices: ~1 GB each
#: at N = 8000).
MAX_LADDER_POINTS = 8000


@dataclass(frozen=True)
class Ladder:
    """How :func:`refine_leading` climbs (refused when invalid).

    Attributes
    ----------
    levels : int
        Levels above level 0 (≥ 1; 2 or more for an observed order).
    target : float or None
        The s_err L/c_p to reach: levels are added beyond `levels` (N ≤ max_points) until the
        estimate is below max(target, rel_target |s L/c_p|); the result says whether it was
        reached (``target_met``). None: the fixed `levels`.
    rel_target : float
        The relative part of that goal (0: absolute only).
    max_points : int
        The largest level a climb toward the target may take.
    pin_translation : bool
        Every level solved with translation pinned (:func:`pulse_spectrum`).
    tol : float
        Newton's step criterion of each level's eigen-solve.
    """

    levels: int = 2
    target: float | None = None
    rel_target: float = 0.0
    max_points: int = MAX_LADDER_POINTS
    pin_translation: bool = False
    tol: float = NEWTON_TOL

    def __post_init__(self):
        if int(self.levels) != self.levels or self.levels < 1:
            raise ValueError(f"levels={self.levels!r} must be an integer >= 1")
        if self.target is not None and not self.target >= 0.0:
            raise ValueError(f"target={self.target!r} must be >= 0 (or None)")
        if not 0.0 <= self.rel_target < 1.0:
            raise ValueError(f"rel_target={self.rel_target!r} must be in [0, 1)")
        if not (self.max_points >= 1 and self.tol > 0.0):
            raise ValueError(f"max_points={self.max_points!r} must be >= 1 and "
                             f"tol={self.tol!r} > 0")


def refine_leading(pulse, params, first, gmap, ladder: Ladder = Ladder(), progress=None,
                   source=None, neighbour=None):
    """The leading eigenvalue on further levels of the map `gmap`, as `ladder` says.

    Parameters
    ----------
    pulse : Pulse (order 4) of level 0, solved on ``gmap(pulse.n_points)``.
    first : PulseSpectrum of `pulse` (level 0), with its leading mode.
    gmap : :class:`slippulse.steady.grid.GridMap` shared by all levels.
    ladder : :class:`Ladder`: the levels, the goal and its cap, pinning and tolerance.
    progress : callable(str) or None, told about each level.
    neighbour : {N: s L/c_p} of the neighbouring pulse's ladder, or None. A level of N points
        starts Newton from the neighbour's value on its level of the same N (the deep pulses,
        0.1 % apart in L, differ by 0.5 % there, while one level moves s L/c_p by 20 %: one
        or two Newton iterations fewer on the finest, costliest level), else from the level
        below; a start from the neighbour that fails is retried from the level below.
    source : the pulse the map was made from (its own grid), or None: where the steady re-solve
        of a level from the level below it does not converge, it is started from this one
        (measured: the deep pulses from a level 0 of N = 2000).

    Returns
    -------
    RefinedRate; status 'failed' (and no number) when a steady re-solve or an eigen-solve fails.
    """
    t0 = time.perf_counter()
    levels, target, rel_target = ladder.levels, ladder.target, ladder.rel_target
    max_points, pin_translation, tol = ladder.max_points, ladder.pin_translation, ladder.tol
    lead = first.leading
    out = RefinedRate(float("nan"), float("nan"), first.rate_unit, [int(first.n_points)],
                      [lead.real], [lead.imag], [float(first.neutral[1].real)],
                      pinned=bool(pin_translation), unit_levels=[first.rate_unit])
    p = pulse
    mode = first.modes[0]["V"] if first.modes else None
    lev = 0
    while True:
        lev += 1
        n = level_points(pulse.n_points, lev)[-1]
        if lev > levels:
            if target is None or n > max_points:
                break
            est = estimate(out.s_per_L_levels)
            if est[1] <= goal(target, rel_target, est[0]):
                break
        q, why = level_pulse(params, p, source, gmap, n)
        if why:
            out.status, out.message = "failed", f"steady Newton on level {lev} {why}"
            break
        res = level_eigen(q, p, params, lead, mode, neighbour, tol, pin_translation)
        if res.status != "converged" or res.sigmas.size == 0:
            out.status = "failed"
            out.message = f"eigen-solve on level {lev} (N = {q.n_points}): {res.message}"
            break
        lead = res.leading
        mode = res.modes[0]["V"]
        p = q
        out.add_level(q.n_points, res)
        if progress:
            progress(f"level {lev}: N={q.n_points} s L/c={lead.real / res.rate_unit:.6g}")
    if out.status == "converged":
        _finish(out, target, rel_target, max_points)
    out.wall_time = time.perf_counter() - t0
    return out


def level_pulse(params, p, source, gmap, n):
    """(the pulse re-solved on ``gmap(n)`` from the level below `p`, else from `source`; '') or
    (None, why)."""
    sol = mapped_pulse(params, p, gmap, n)
    if not sol.stats.converged and source is not None:
        sol = mapped_pulse(params, source, gmap, n)
    if not sol.stats.converged:
        return None, f"(N = {sol.problem.n}) did not converge: {sol.stats.message}"
    return sol.to_pulse(), ""


def level_eigen(q, p, params, lead, mode, neighbour, tol, pin_translation):
    """The leading eigenvalue of level `q` from the level below (`p`, its leading σ and mode):
    Newton from the neighbour's value on this N first where there is one, else (or where that
    fails) from the level below's σ at equal σL/c, with its mode interpolated (cubic: the first
    Newton step lands 4.6e-7 c/L from the eigenvalue, against 4.9e-6 from a linear one,
    measured at 1.05 τ_min, N = 1000 → 1414; one iteration fewer). Pinned, σ_t = 0 by
    construction: the neutral pair is not computed above level 0."""
    starts = [lead * (q.c_p / q.L) / (p.c_p / p.L)]
    if neighbour and int(q.n_points) in neighbour:
        starts.insert(0, complex(neighbour[int(q.n_points)]) * (q.c_p / q.L))
    gmode = None
    if mode is not None:
        gmode = [CubicSpline(p.xi, mode.real)(q.xi) + 1j * CubicSpline(p.xi, mode.imag)(q.xi)]
    for start in starts:
        res = pulse_spectrum(q, params, guesses=[start], extra=False, tol=tol,
                             guess_modes=gmode, pin_translation=pin_translation,
                             neutral=not pin_translation)
        if res.status == "converged" and res.sigmas.size:
            break
    return res


def _finish(out, target, rel_target, max_points):
    """The estimate of a converged ladder (s, s_err, order, rule; the check extrapolations) and
    whether it meets the goal."""
    out.s, out.s_err, out.order, out.rule = estimate(out.s_levels)
    out.s_per_L, out.s_err_per_L = estimate(out.s_per_L_levels)[:2]
    out.s_extrapolated = richardson(out.s_levels)[0]
    if not out.pinned:              # pinned: σ_t = 0 by construction, nothing to check
        out.translation_extrapolated, out.translation_err = \
            richardson(out.translation_levels)[:2]
    out.message = (f"{len(out.s_levels)} levels, N = "
                   f"{'/'.join(str(n) for n in out.n_points)}, {out.rule}"
                   + (f" (order {out.order:.2f})" if out.rule == "three-level" else ""))
    if target is not None:
        sl, el = out.per_length()
        out.target = goal(target, rel_target, sl)
        out.target_met = bool(el <= out.target)
        if not out.target_met:
            out.message += (f"; target s_err L/c_p <= {out.target:g} not reached by N = "
                            f"{out.n_points[-1]} (next level > {max_points} points)")
