"""The spectrum of every pulse of a file, with the leading rate's error estimate and an optional
count (``slippulse steady stability``; method: docs/spectrum.md).

Per pulse (:func:`pulse_task`): level 0, the pulse re-solved on a map of its grid
(:data:`LEVEL0_ATTEMPTS`); :func:`slippulse.spectrum.pulse.pulse_spectrum` on it, tracked from its
neighbour (:class:`Tracking`); :func:`slippulse.spectrum.refine.refine_leading` on a ladder of
mapped grids (s ± s_err); :func:`slippulse.spectrum.count.count_unstable` if asked. The options
travel as one :class:`SpectrumSettings`; each result is stored by
:func:`slippulse.spectrum.pulse.write_spectrum` in the pulse's group as it arrives, with the
settings and the level-0 attempt that produced it, so that a rerun resumes. The pulses run on
:class:`slippulse.core.executor.TaskPool` (this process, a local Dask cluster or a scheduler).
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

from ..core.errors import UsageError
from ..core.executor import ExecutorSettings, TaskPool
from ..steady.grid import GridMap
from .count import count_unstable
from .pulse import (MIN_RE, NEWTON_TOL, PulseSpectrum, order4_pulse, polish_located,
                    pulse_spectrum, read_spectrum, write_spectrum)
from .refine import (MAX_LADDER_POINTS, Ladder, check_refinable, level0_size, level_points,
                     mapped_pulse, refine_leading)

COUNT_EVALS = 400           # default budget of det M evaluations per count (docs/spectrum.md §5)


def count_checkpoint_path(path, label):
    """The file beside the family file that keeps a count's evaluations until it converges."""
    return f"{path}.count-{label}.npz"


@dataclass
class SpectrumReport:
    results: list = field(default_factory=list)     # PulseSpectrum, in the order computed
    skipped: list = field(default_factory=list)     # labels with a stored converged spectrum
    failed: list = field(default_factory=list)
    wall_time: float = 0.0


def check_family_file(path, labels=None):
    """Labels to analyse (decreasing τ_d), after checking the file: readable HDF5 with slippulse
    parameters and converged mode-III pulses. Raises SchemaError naming the problem."""
    from ..core.h5io import (SchemaError, check_pulse_group, labels_in, open_h5,
                             pulse_converged, read_parameters, require_converged)
    with open_h5(path) as h5:
        try:
            params = read_parameters(h5, path)
        except SchemaError as exc:
            raise SchemaError(f"{path}: not a slippulse pulse file ({exc})") from None
        present = labels_in(h5, path)
        if not present:
            raise SchemaError(f"{path}: holds no pulses")
        grp = h5["pulses"]
        if labels:
            missing = [lab for lab in labels if lab not in grp]
            if missing:
                raise SchemaError(f"{path}: no pulse {missing[0]!r}; present: "
                                  f"{present[0]} ... {present[-1]} ({len(present)} pulses)")
            chosen = [lab for lab in present if lab in set(labels)]
        else:
            chosen = present
        good = []
        for lab in chosen:
            a = grp[lab].attrs
            check_pulse_group(grp[lab], path)
            if not pulse_converged(grp[lab], path):
                if labels:
                    require_converged(path, [lab], hint="its spectrum would be meaningless")
                continue
            if str(a.get("mode", "III")) != "III":
                raise SchemaError(f"{path}: pulse {lab} is a mode-{a.get('mode')} pulse; the "
                                  f"spectrum is for mode III")
            good.append(lab)
        if not good:
            raise SchemaError(f"{path}: holds no converged pulse")
    return good, params


#: Default smallest N of the spectrum's level 0 (a pulse with fewer points is mapped onto this
#: many). Pinned, the ladder from N = 1000 is in the asymptotic range at 1.2–1.05 τ_min
#: (observed order 3.6–4.1, docs/spectrum.md §4).
MIN_SPECTRUM_POINTS = 1000
#: Default largest N of level 0 (a pulse with more points is mapped onto this many). Measured,
#: pinned: at 1.008993 τ_min (own N = 3542) level 0 at N = 2828 is 1.2e-5 from the converged
#: s L/c_p; at 1.009365 τ_min N = 2000 is not resolved (s L/c_p = 0.0093 against 2.2e-4).
MAX_SPECTRUM_POINTS = 2828
#: Default number of levels above level 0 (two levels: the last correction is the error); more
#: are added until the goal below is met.
DEFAULT_LEVELS = 1
#: Default accuracy goal of the ladder: s_err L/c_p <= max(DEFAULT_TARGET, DEFAULT_REL_TARGET
#: |s L/c_p|) (1e-4 below 1.02 τ_min, where s L/c_p < 0.02).
DEFAULT_TARGET = 1e-4
DEFAULT_REL_TARGET = 1e-3
#: A level 0 clipped below the pulse's own N gives way to the own N once its re-solve has not
#: halved max|r| over this many Newton iterations. Where the clipped grid holds the pulse the
#: re-solve converges in 3-5 iterations, each halving max|r| or better (measured at L = 0.42-2.6
#: km, N = 2828 on 3542-point pulses); where it cannot (2.8 km and deeper) max|r| stalls at
#: 1e-4 after two, and 60 iterations cost 30 s of a 143 s pulse (BENCHMARKS.md).
LEVEL0_CREEP = 4
#: A level 0 with fewer points than the pulse's own grid (clipped to max_points, or given)
#: climbs at least this many levels above it, so that its estimate observes an order: on two
#: levels the last correction is the error, and a clipped level 0 that is not in the
#: asymptotic range hides it. Measured: at 6.30 km the clipped ladder 2828/3999 gave
#: s L/c_p = 6.330e-5 ± 3.5e-6 against the three-level 7.102e-5 ± 2.5e-7 on the own ladder,
#: 2.1 times the summed bars. Not where the finest level would exceed MAX_LADDER_POINTS.
CLIPPED_LEVELS = 2


@dataclass(frozen=True)
class SpectrumSettings:
    """How the spectrum of each pulse is computed (the options of ``slippulse steady
    stability``); printed by the command and stored with every result (:meth:`stored`, the
    ``setting_*`` attributes a rerun compares before it keeps a stored spectrum).

    Attributes
    ----------
    levels : int
        Levels above level 0 for the leading eigenvalue's error estimate
        (:func:`slippulse.spectrum.refine.refine_leading`: grids of N_0 √2^k points sampled
        from one smooth map of the pulse's grid); a level that fails marks the pulse failed.
        0: no estimate (no s, s_err stored).
    target, rel_target : float
        The goal s_err L/c_p <= max(target, rel_target |s L/c_p|); levels are added beyond
        `levels` until it is met (or the next level would exceed
        :data:`slippulse.spectrum.refine.MAX_LADDER_POINTS`). target None: the fixed `levels`.
    min_points, max_points : int
        Level 0 has N_0 = N clipped to [min_points, max_points] (the steady equations
        re-solved on the map; with levels = 0 and N inside, the pulse's own grid).
        max_points None: no bound.
    level0_points : int or None
        Level 0 has exactly this many points (overrides the clip; no fallback).
    pin_translation : bool
        Solve with translation pinned (docs/spectrum.md §2).
    extra : bool
        Also seek the eigenvalues beyond the leading one.
    tol : float
        Newton's step criterion of the eigen-solve.
    count_box : tuple or None
        (x0, x1, y1) in c_p/L: also count the eigenvalues in that box by the argument
        principle (x1 and y1 raised to 1.5 times the leading s L/c_p where larger).
    count_evals : int
        Budget of determinant evaluations of the count.
    """

    levels: int = DEFAULT_LEVELS
    target: float | None = DEFAULT_TARGET
    rel_target: float = DEFAULT_REL_TARGET
    min_points: int = MIN_SPECTRUM_POINTS
    max_points: int | None = MAX_SPECTRUM_POINTS
    level0_points: int | None = None
    pin_translation: bool = True
    extra: bool = True
    tol: float = NEWTON_TOL
    count_box: tuple | None = None
    count_evals: int = COUNT_EVALS

    def __post_init__(self):
        if not (isinstance(self.levels, int) and self.levels >= 0):
            raise UsageError(f"levels={self.levels!r}: an integer >= 0")
        if self.target is not None and not (np.isfinite(self.target) and self.target > 0):
            raise UsageError(f"target={self.target!r}: a number > 0, or None")
        if not 0.0 <= self.rel_target < 1.0:
            raise UsageError(f"rel_target={self.rel_target!r}: a number in [0, 1)")
        if self.count_box is not None:
            x0, x1, y1 = (float(b) for b in self.count_box)
            if not (0.0 < x0 < x1 and y1 > 0.0):
                raise UsageError(f"count_box={self.count_box!r}: need 0 < x0 < x1 and y1 > 0")
            object.__setattr__(self, "count_box", (x0, x1, y1))

    def stored(self) -> dict:
        """The ``setting_*`` attributes of a stored spectrum (those a rerun compares)."""
        return {"tol": self.tol, "extra": int(bool(self.extra)), "min_re_c_over_L": MIN_RE,
                "levels": int(self.levels), "count": int(self.count_box is not None),
                "min_points": int(self.min_points), "ladder": "smooth map, ratio sqrt(2)",
                "target": -1.0 if self.target is None else float(self.target),   # -1: none
                "rel_target": 0.0 if self.target is None else float(self.rel_target),
                "max_points": int(self.max_points or 0),                         # 0: no bound
                "pin_translation": int(bool(self.pin_translation)),
                "level0_points": int(self.level0_points or 0)}                   # 0: clipped

    def __str__(self):
        return ", ".join(f"{k}={v}" for k, v in vars(self).items())


#: Values a stored spectrum lacks when it was written before the setting existed (it was
#: computed as with these).
UNSET_STORED = {"pin_translation": 0, "level0_points": 0, "rel_target": 0.0, "max_points": 0}


# --------------------------------------------------------------------------- level 0


def solve_level0(pulse, params, gmap, n, creep=0):
    """Level 0: the pulse re-solved on ``gmap(n)`` (creep > 0: give up once max|r| has not
    halved over `creep` iterations); (pulse, '') or (the pulse given, why) on failure."""
    sol = mapped_pulse(params, pulse, gmap, n, creep=creep)
    if not sol.stats.converged:
        return pulse, f"did not converge: {sol.stats.message}"
    return sol.to_pulse(), ""


@dataclass(frozen=True)
class Level0Attempt:
    """One way to build level 0: on the clipped N ('clip', :func:`level0_size`) or on the
    pulse's own N ('own'), giving up after `creep` iterations that do not halve max|r| (0: the
    solver's own limit). `cases`: where it is tried — 'unclipped' (level 0 at the given or the
    own N), 'clipped' (the clip lies below the own N), 'clip failed above' (clipped, and the
    neighbour tracked from, of the same own N, had its ladder start at its own N)."""

    grid: str
    creep: int
    cases: frozenset

    def points(self, n0, n_own):
        return int(n0) if self.grid == "clip" else int(n_own)

    def describe(self, n0, n_own):
        where = (f"the clipped N = {n0}" if self.grid == "clip" and n0 != n_own
                 else f"the pulse's own N = {n_own}" if self.grid == "own"
                 else f"N = {n0}")
        return f"level 0 on {where}" + (f" (creep stop {self.creep})" if self.creep else "")


#: The level-0 attempts, in order; the first that converges is level 0, and the stored
#: spectrum records which one it was (``level0_attempt``). Down the family the pulses get
#: longer, so a clip that failed on the neighbour fails here as well: the own N first (a
#: re-solve on the clip would give up after LEVEL0_CREEP iterations, 4–6 s at N = 2828), then
#: the clip (at 6.3–6.6 km the own N fails where the clip holds); without the creep stop, the
#: own N (converges only so at 6.0 and 6.68 km) and last the clip (at 6.57 km it converges so in
#: 27 iterations where the own N does not in 60). Not the clip first there: at 1.008393 τ_min
#: the clip's level 0 has a spurious real eigenvalue at 1.9e-6 c/L and its ladder fails.
LEVEL0_ATTEMPTS = (
    Level0Attempt("own", LEVEL0_CREEP, frozenset({"clip failed above"})),
    Level0Attempt("clip", LEVEL0_CREEP, frozenset({"clipped", "clip failed above"})),
    Level0Attempt("own", 0, frozenset({"clipped", "clip failed above"})),
    Level0Attempt("clip", 0, frozenset({"unclipped", "clip failed above"})),
)


def level0(source, params, settings, tracking, levels):
    """Level 0 of `source` (its own grid state order 4) by the first :data:`LEVEL0_ATTEMPTS`
    that converges. Returns (pulse, levels, attempt text, why): `levels` raised by
    :func:`clipped_levels` where level 0 lies below the own N; why '' unless all failed."""
    n_own = int(source.n_points)
    n0 = level0_size(n_own, settings.min_points, settings.level0_points, settings.max_points)
    if not levels and n0 == n_own:
        return source, levels, "the pulse's own grid", ""
    gmap = GridMap(source.xi)
    if settings.level0_points is not None or n0 >= n_own:
        case = "unclipped"
    elif tracking.clip_failed_above(n_own, source, levels):
        case = "clip failed above"
    else:
        case = "clipped"
    whys = []
    for attempt in LEVEL0_ATTEMPTS:
        if case not in attempt.cases:
            continue
        what = attempt.describe(n0, n_own)
        n = attempt.points(n0, n_own)
        if attempt.grid == "own":
            try:
                check_refinable(source, levels, level0_points=n_own)
            except UsageError as exc:
                whys.append(f"{what}: {exc}")
                continue
        pulse, why = solve_level0(source, params, gmap, n, attempt.creep)
        if not why:
            return pulse, clipped_levels(levels, n, n_own), what, ""
        whys.append(f"{what}: {why}")
    return source, levels, "", "steady re-solve failed: " + "; ".join(whys)


def clipped_levels(levels, n0, n_own):
    """Levels above a level 0 of n0 points for a pulse of n_own points: `levels`, raised to
    :data:`CLIPPED_LEVELS` where n0 < n_own (and the ladder fits MAX_LADDER_POINTS)."""
    if levels and n0 < n_own and level_points(n0, CLIPPED_LEVELS)[-1] <= MAX_LADDER_POINTS:
        return max(int(levels), CLIPPED_LEVELS)
    return levels


def short_clipped_ladder(stored, n_own, levels):
    """A stored spectrum whose ladder started below the pulse's own N with fewer levels than
    :func:`clipped_levels` asks for now (computed before that rule): not kept on a rerun."""
    n = stored.get("refine_n_points")
    if n is None or not levels or len(n) == 0:
        return False
    n = [int(k) for k in np.atleast_1d(n)]
    return len(n) - 1 < clipped_levels(levels, n[0], int(n_own))


# --------------------------------------------------------------------------- tracking


#: Largest ratio of τ_d steps, (this pulse − the neighbour)/(the neighbour − the one before it),
#: over which :meth:`Tracking.predicted_ladder` extrapolates; beyond it the neighbour's values.
EXTRAPOLATE_RATIO = 2.0


def ladder_of(n_points, s_per_L):
    """{N_k: s_k L_k/c_k}: a pulse's refinement levels."""
    return {int(k): float(v) for k, v in zip(n_points, s_per_L)}


def stored_ladder(stored):
    """:func:`ladder_of` a stored spectrum (empty where it has no levels)."""
    if not all(k in stored for k in ("refine_n_points", "refine_s_levels",
                                     "refine_rate_unit_levels")):
        return {}
    return ladder_of(np.atleast_1d(stored["refine_n_points"]),
                     np.atleast_1d(stored["refine_s_levels"])
                     / np.atleast_1d(stored["refine_rate_unit_levels"]))


def moved_mode(x, x_prev, V_prev):
    """The neighbour's mode V₁(ξ/L) moved onto this pulse's ξ/L: cubic spline inside its range,
    its end values outside (where the mode has decayed). Cubic, not linear: Newton's first step
    from it lands nearer (two to four assemblies fewer at level 0, measured at L = 2.3 km)."""
    from scipy.interpolate import CubicSpline
    xc = np.clip(x, x_prev[0], x_prev[-1])
    V_prev = np.asarray(V_prev)
    return CubicSpline(x_prev, V_prev.real)(xc) + 1j * CubicSpline(x_prev, V_prev.imag)(xc)


@dataclass(frozen=True)
class Tracking:
    """What the next pulse's search starts from: the neighbour just computed (or stored).

    sigmas : its eigenvalues (1/s), by decreasing Re σ; empty: no neighbour (default search).
    rate_unit : its c_p/L (1/s).
    ladder : its refinement levels {N: s L/c_p}.
    tau : its τ_d/τ_min (None: read from a stored spectrum, no extrapolation).
    before : (τ_d/τ_min, ladder) of the pulse tracked before it, or None.
    mode : (ξ/L, V₁) of its leading mode, or None.
    """

    sigmas: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))
    rate_unit: float = 1.0
    ladder: dict = field(default_factory=dict)
    tau: float | None = None
    before: tuple | None = None
    mode: tuple | None = None

    @classmethod
    def from_guess(cls, s_per_L):
        """A start at σ L/c_p = `s_per_L` for the first pulse (a deep pulse, rates below the
        search's MIN_RE c_p/L, with no spectrum computed above)."""
        return cls(np.array([complex(s_per_L)]), 1.0)

    @classmethod
    def from_stored(cls, stored):
        """From a stored spectrum (its eigenvalues, ladder and leading mode)."""
        mode = None
        if stored["sigma"].size and stored["V"].shape[0]:
            mode = (np.asarray(stored["xi"], float) / float(stored["L"]), stored["V"][0])
        return cls(stored["sigma"], float(stored["rate_unit_c_over_L"]), stored_ladder(stored),
                   mode=mode)

    def after(self, res, pulse):
        """The state after `res`, the converged spectrum of `pulse` started from this one."""
        ref = res.refined
        before = (self.tau, self.ladder) if self.tau is not None and self.ladder else None
        mode = (pulse.xi / pulse.L, res.modes[0]["V"]) if res.modes else None
        return Tracking(res.sigmas, res.rate_unit,
                        ladder_of(ref.n_points, ref.s_per_L_levels) if ref is not None else {},
                        float(pulse.tau_d_ratio), before, mode)

    def predicted_ladder(self, tau):
        """{N: s L/c_p} expected at τ_d/τ_min = `tau`: the neighbour's ladder, extrapolated
        linearly in τ_d through the ladder of the pulse before it wherever that has the same
        level (and the two τ_d steps go the same way, the new one at most EXTRAPOLATE_RATIO
        times the old). Newton's start at each level: the deep pulses' rates change by ≈ 1 %
        of s from one pulse to the next, as much as the step criterion, so a start at the
        neighbour's value often costs a second assembly of M(σ) that this start saves."""
        if not self.ladder or self.before is None or self.tau is None:
            return dict(self.ladder)
        t2, older = self.before
        step, back = tau - self.tau, self.tau - t2
        if back == 0.0 or not 0.0 < step / back <= EXTRAPOLATE_RATIO:
            return dict(self.ladder)
        w = step / back
        return {n: v + w * (v - older[n]) if n in older else v for n, v in self.ladder.items()}

    def clip_failed_above(self, n_own, source, levels):
        """Whether the neighbour, of the same own N, had its ladder start at its own N (its
        clip failed, or was not asked for) and this pulse's own N can carry the levels."""
        if not self.ladder or min(self.ladder) != int(n_own):
            return False
        try:
            check_refinable(source, levels, level0_points=n_own)
        except UsageError:
            return False
        return True

    def starts(self, pulse, predicted):
        """(guesses, guess modes) of :func:`pulse_spectrum` on `pulse`: the neighbour's leading
        eigenvalue at equal σL/c (or the predicted ladder's value for a real one at this N),
        and its mode moved onto this pulse."""
        if not self.sigmas.size:
            return [], None
        unit = pulse.c_p / pulse.L
        s0 = self.sigmas[0]
        guesses = [complex(s0.real, abs(s0.imag)) * unit / self.rate_unit]
        if s0.imag == 0.0 and int(pulse.n_points) in predicted:
            guesses = [complex(predicted[int(pulse.n_points)]) * unit]
        modes = [moved_mode(pulse.xi / pulse.L, *self.mode)] if self.mode is not None else None
        return guesses, modes


NO_TRACKING = Tracking()


def seed_tracking(path, chosen):
    """Tracking from the nearest pulse above chosen[0] with a stored converged spectrum that has
    an eigenvalue; :data:`NO_TRACKING` if there is none."""
    if not chosen:
        return NO_TRACKING
    every, _ = check_family_file(path)
    if chosen[0] not in every:
        return NO_TRACKING
    for lab in reversed(every[:every.index(chosen[0])]):
        stored = read_spectrum(path, lab)
        if stored is not None and stored.get("status") == "converged" and stored["sigma"].size:
            return Tracking.from_stored(stored)
    return NO_TRACKING


# --------------------------------------------------------------------------- one pulse


def failed_spectrum(label, pulse, message):
    """A PulseSpectrum that stores the failure and no eigenvalue."""
    return PulseSpectrum(label, np.zeros(0, complex), [], np.zeros(2), float("nan"),
                         pulse.c_p / pulse.L, int(pulse.n_points), "failed", message, 0.0)


def _count(res, settings, checkpoint, level_progress, executor):
    """The count of the eigenvalues in the settings' box (raised to 1.5 times the leading rate),
    its evaluations kept in `checkpoint` until it converges."""
    lead = res.leading.real / res.rate_unit if res.sigmas.size else 0.0
    box0 = settings.count_box
    box = (box0[0], max(box0[1], 1.5 * lead), max(box0[2], 1.5 * lead))
    cnt = count_unstable(res.operator, box, max_evals=settings.count_evals, executor=executor,
                         progress=(lambda k: level_progress(f"count: {k} det"))
                         if level_progress else None, checkpoint=checkpoint)
    if cnt.status == "converged":
        if checkpoint and os.path.exists(checkpoint):
            os.remove(checkpoint)
    elif checkpoint and os.path.exists(checkpoint):
        cnt.message += (f"; its evaluations are kept in {checkpoint}: the same count with a "
                        "larger budget goes on from them")
    return cnt


def _counted(res, pulse, params, settings, lab, checkpoint, level_progress, executor):
    """`res` with the count of its level 0 and the count's zeros polished
    (:func:`~.pulse.polish_located`). Where one of them lies right of the search's leading
    eigenvalue, the search is made again from it (``leading_from = "count"``) and refined from
    there: a search tracked from a neighbour follows *its* mode, which need not lead here."""
    cnt = _count(res, settings, checkpoint, level_progress, executor)
    located, modes = (polish_located(res.operator, cnt, res.sigmas, settings.tol) if cnt.count
                      else (np.zeros(0), {}))
    lead = res.leading.real if res.sigmas.size else -math.inf
    if located.size and located[0].real > lead + 1e-6 * abs(located[0]):
        # Newton from the polished (σ, V): a start from σ alone goes through Arnoldi, whose
        # second candidate may converge far outside the box (834 c_p/L on the two-hump pulse)
        mode = modes.get(located[0])
        again = pulse_spectrum(pulse, params, guesses=[located[0]], extra=settings.extra,
                               tol=settings.tol, label=lab,
                               guess_modes=None if mode is None else [mode],
                               pin_translation=settings.pin_translation)
        if again.status == "converged" and again.sigmas.size and \
                abs(again.leading - located[0]) <= 1e-6 * abs(located[0]):
            res, again.leading_from = again, "count"
    res.count = cnt
    return res


def pulse_task(lab, pulse, params, tracking, settings, checkpoint=None, level_progress=None,
               count_executor=None):
    """The spectrum of one pulse, started from `tracking`: level 0, the eigenvalues, the
    refinement and the count of `settings`. Writes nothing but the count's `checkpoint`.
    Returns (PulseSpectrum, the tracking state after it: unchanged where the pulse failed)."""
    levels = settings.levels
    if levels:
        check_refinable(pulse, levels, settings.min_points, settings.level0_points,
                        settings.max_points)
    source = order4_pulse(pulse, params)
    pulse, levels, attempt, why = level0(source, params, settings, tracking, levels)
    if why:
        return failed_spectrum(lab, pulse, why), tracking
    predicted = tracking.predicted_ladder(float(pulse.tau_d_ratio))
    guesses, modes = tracking.starts(pulse, predicted)
    res = pulse_spectrum(pulse, params, guesses=guesses, extra=settings.extra, tol=settings.tol,
                         label=lab, guess_modes=modes, pin_translation=settings.pin_translation)
    if res.status == "converged" and settings.count_box is not None:
        res = _counted(res, pulse, params, settings, lab, checkpoint, level_progress,
                       count_executor)
    res.level0_attempt = attempt
    if res.status == "converged" and res.sigmas.size and levels:
        gmap = GridMap(source.xi)
        ladder = Ladder(levels, target=settings.target, rel_target=settings.rel_target,
                        pin_translation=settings.pin_translation, tol=settings.tol)
        # the neighbour's ladder is of the mode it tracked: not this one where the count's led
        neighbour = (predicted or None) if res.leading_from == "search" else None
        res.refined = refine_leading(pulse, params, res, gmap, ladder, progress=level_progress,
                                     source=source, neighbour=neighbour)
        if res.refined.status != "converged":
            res.status = "failed"
            res.message = f"refinement failed: {res.refined.message}"
    res.operator = None                             # N×N matrices: not kept per pulse
    if res.status != "converged":                   # a failure stores no eigenvalue
        res.sigmas = np.zeros(0, complex)
        res.modes = []
        return res, tracking
    return res, tracking.after(res, pulse)


def _worker_pulse_task(*args):
    """:func:`pulse_task` in a worker process, whose malloc keeps freed memory as the
    command's own process does (fewer page faults on the N×N arrays)."""
    from ..core.memory import keep_freed_memory
    keep_freed_memory()
    return pulse_task(*args)


# --------------------------------------------------------------------------- the family


@dataclass
class Run:
    """A contiguous run of pulses to compute, taken from the top (step +1, tracking down from
    `seed`) and, by a second worker, from the bottom (step −1, from the default search), one
    pulse at a time, until the two meet: their work balances whatever each pulse costs."""

    labels: list
    seed: Tracking = NO_TRACKING
    lo: int = 0
    hi: int = -1
    ends: int = 0                # cursors working on it

    def __post_init__(self):
        self.hi = len(self.labels) - 1

    @property
    def left(self):
        return self.hi - self.lo + 1

    def claim(self, step):
        """The next label from the top (step +1) or the bottom (step −1); None once met."""
        if self.lo > self.hi:
            return None
        if step > 0:
            self.lo += 1
            return self.labels[self.lo - 1]
        self.hi -= 1
        return self.labels[self.hi + 1]


@dataclass
class Cursor:
    """One worker's walk: its run, its direction and the tracking state it carries."""

    run: Run
    step: int
    tracking: Tracking


def split_runs(plan, seed, pieces):
    """The pulses to compute of `plan` ((label, kept stored spectrum or None), in order) as
    :class:`Run` objects: contiguous between kept ones (each seeded from the kept one above,
    the first from `seed`), the longest halved until there are at least `pieces`."""
    runs, cur, above = [], [], seed
    for lab, kept in plan:
        if kept is None:
            cur.append(lab)
            continue
        if cur:
            runs.append(Run(cur, above))
            cur = []
        above = Tracking.from_stored(kept)
    if cur:
        runs.append(Run(cur, above))
    while len(runs) < pieces:
        k = max(range(len(runs)), key=lambda i: len(runs[i].labels), default=None)
        if k is None or len(runs[k].labels) < 2:
            break
        r = runs[k]
        half = len(r.labels) // 2
        runs[k:k + 1] = [Run(r.labels[:half], r.seed), Run(r.labels[half:], NO_TRACKING)]
    return runs


def _next_cursor(runs, cursor=None):
    """A cursor for a free worker: the top of the next run not started, else the bottom of the
    started run with the most pulses left and one worker; None when there is no work."""
    for run in runs:
        if run.ends == 0 and run.left > 0:
            run.ends = 1
            return Cursor(run, +1, run.seed)
    busy = [r for r in runs if r.ends == 1 and r.left > 1]
    if not busy:
        return None
    run = max(busy, key=lambda r: r.left)
    run.ends = 2
    return Cursor(run, -1, NO_TRACKING)


def run_spectrum(path, settings: SpectrumSettings | None = None, labels=None, overwrite=False,
                 guess=None, executor: ExecutorSettings | None = None, progress=None,
                 level_progress=None):
    """Spectrum of every (or each named) converged pulse of `path`, stored in its group.

    Pulses are taken by decreasing τ_d; each starts from its neighbour's eigenvalues at equal
    σL/c (:class:`Tracking`), else from the default search (which below MIN_RE c/L finds the
    leading real eigenvalue by the sign of det M). A stored converged spectrum with the same
    :meth:`SpectrumSettings.stored` settings is kept (resume) unless `overwrite`. A failed
    pulse stores its status and message and no eigenvalue. progress(label, result or None,
    stored dict or None); level_progress(text) about each level and count evaluation (serial
    runs only).

    guess : s L/c_p (> 0) to start the first chosen pulse's search from, instead of the
        spectrum stored above it (a deep pulse with no computed spectrum above).
    executor : where the pulses run (:class:`slippulse.core.executor.ExecutorSettings`). With
        more than one worker, the pulses to compute are cut into runs (:func:`split_runs`),
        each served by one worker from the top, tracking down, and, where workers are free, a
        second from the bottom, tracking up from the default search (:class:`Run`); this
        process writes each result as it arrives. A pulse's Newton start depends on which
        worker reached it: the values agree within Newton's tolerance, the ladders within
        their bars. Serially (one worker, no scheduler) a count's determinants run here; with
        one pulse to compute and several workers, on the workers.
    """
    from ..core.h5io import read_pulse
    settings = settings if settings is not None else SpectrumSettings()
    executor = executor if executor is not None else ExecutorSettings()
    t0 = time.perf_counter()
    chosen, params = check_family_file(path, labels)
    stored_settings = settings.stored()
    rep = SpectrumReport()
    seed = seed_tracking(path, chosen) if guess is None else Tracking.from_guess(guess)

    plan = []                                        # (label, stored spectrum to keep or None)
    for lab in chosen:
        stored = None if overwrite else read_spectrum(path, lab)
        keep = stored is not None and stored.get("status") == "converged" and all(
            stored.get(f"setting_{k}", UNSET_STORED.get(k)) == v
            for k, v in stored_settings.items()) \
            and not short_clipped_ladder(stored, _own_points(path, lab), settings.levels)
        plan.append((lab, stored if keep else None))
        if keep:
            rep.skipped.append(lab)
            if progress:
                progress(lab, None, stored)
    todo = [lab for lab, kept in plan if kept is None]
    one_pulse_count = len(todo) == 1 and settings.count_box is not None
    pulse_pool = executor if not one_pulse_count else ExecutorSettings()
    with TaskPool(pulse_pool if todo else ExecutorSettings()) as pool:
        runs = split_runs(plan, seed, max(1, (pool.n_workers + 1) // 2))
        task = _worker_pulse_task if pool.parallel else pulse_task
        owner = {}

        def launch(cursor):
            while cursor is not None:
                lab = cursor.run.claim(cursor.step)
                if lab is not None:
                    pulse, _ = read_pulse(path, lab)
                    h = pool.submit(task, lab, pulse, params, cursor.tracking, settings,
                                    count_checkpoint_path(path, lab),
                                    None if pool.parallel else level_progress,
                                    executor if one_pulse_count else None)
                    owner[h] = (lab, cursor)
                    return
                cursor = _next_cursor(runs)

        for _ in range(pool.n_workers):
            launch(_next_cursor(runs))
        for h, out, err in pool.completed():
            lab, cursor = owner.pop(h)
            if isinstance(err, UsageError):
                raise err
            if err is not None:
                raise RuntimeError(f"spectrum of {lab} failed: {type(err).__name__}: {err}") \
                    from err
            res, cursor.tracking = out
            write_spectrum(path, res, stored_settings,
                           extra_attrs={"settings": str(settings),
                                        "level0_attempt": getattr(res, "level0_attempt", "")})
            rep.results.append(res)
            if res.status != "converged":
                rep.failed.append(lab)
            if progress:
                progress(lab, res, None)
            launch(cursor)
    rep.wall_time = time.perf_counter() - t0
    return rep


def _own_points(path, label):
    """The number of points of a pulse's own grid in its file."""
    from ..core.h5io import check_pulse_group, open_h5
    with open_h5(path) as h5:
        return check_pulse_group(h5["pulses"][label], path).n_points
