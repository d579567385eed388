"""The spectrum of every pulse of a file, with the leading rate's error estimate and an optional
count (``slippulse steady stability``; method: docs/spectrum.md).

Per pulse: :func:`slippulse.stability.spectrum.pulse_spectrum` on the pulse's grid (tracked from
its neighbour), :func:`slippulse.stability.refine.refine_leading` on a ladder of mapped grids (s ± s_err),
:func:`slippulse.stability.count.count_unstable` if asked; stored by
:func:`slippulse.stability.spectrum.write_spectrum` in the pulse's group, resumable.
"""
from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass, field

import numpy as np

from ..core.errors import UsageError
from ..core.h5io import label_ratio
from ..steady.grid import GridMap
from .count import count_unstable
from .refine import (MAX_LADDER_POINTS, check_refinable, level0_size, level_points,
                     mapped_pulse, refine_leading)
from .spectrum import (MIN_RE, NEWTON_TOL, PulseSpectrum, order4_pulse, pulse_spectrum,
                       read_spectrum, write_spectrum)

COUNT_EVALS = 400           # default budget of det M evaluations per count (docs/spectrum.md §6)


def count_checkpoint_path(path, label):
    """The file beside the family file that keeps a count's evaluations until it converges."""
    return f"{path}.count-{label}.npz"


@dataclass
class SpectrumReport:
    results: list = field(default_factory=list)     # PulseSpectrum, in the order computed
    skipped: list = field(default_factory=list)     # labels with a stored converged spectrum
    failed: list = field(default_factory=list)
    wall_time: float = 0.0


def _by_decreasing_ratio(label):
    """Sort key of pulse labels by decreasing τ_d (names that are no pulse label: 0)."""
    r = label_ratio(label)
    return -r if np.isfinite(r) and r >= 0 else 0.0


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
#: (observed order 3.6–4.1, docs/spectrum.md §5).
MIN_SPECTRUM_POINTS = 1000
#: Default largest N of level 0 (a pulse with more points is mapped onto this many). Measured,
#: pinned: at 1.008993 τ_min (own N = 3542) level 0 at N = 2828 is 1.2e-5 from the converged
#: s L/c_p; at 1.009365 τ_min N = 2000 is not resolved (s L/c_p = 0.0093 against 2.2e-4).
MAX_SPECTRUM_POINTS = 2828
#: Default number of levels above level 0 (two levels: the last correction is the error); more
#: are added until the goal below is met.
DEFAULT_LEVELS = 1
#: Default accuracy goal of the ladder: s_err L/c_p <= max(DEFAULT_TARGET, DEFAULT_REL_TARGET
#: |s L/c_p|) (issue 17: 1e-4 below 1.02 τ_min, where s L/c_p < 0.02).
DEFAULT_TARGET = 1e-4
DEFAULT_REL_TARGET = 1e-3


#: A level 0 clipped below the pulse's own N gives way to the own N once its re-solve has not
#: halved max|r| over this many Newton iterations. Where the clipped grid holds the pulse the
#: re-solve converges in 3-5 iterations, each halving max|r| or better (measured at L = 0.42-2.6
#: km, N = 2828 on 3542-point pulses); where it cannot (2.8 km and deeper) max|r| stalls at
#: 1e-4 after two and the 60 iterations it used to spend cost 30 s of a 143 s pulse
#: (BENCHMARKS.md, stop 36).
LEVEL0_CREEP = 4
#: A level 0 with fewer points than the pulse's own grid (clipped to max_points, or given)
#: climbs at least this many levels above it, so that its estimate observes an order: on two
#: levels the last correction is the error, and a clipped level 0 that is not in the
#: asymptotic range hides it. Measured (stop 37): at 6.30 km the clipped ladder 2828/3999 gave
#: s L/c_p = 6.330e-5 ± 3.5e-6 against the three-level 7.102e-5 ± 2.5e-7 on the own ladder,
#: 2.1 times the summed bars. Not where the finest level would exceed MAX_LADDER_POINTS.
CLIPPED_LEVELS = 2


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


def _own_points(path, label):
    """The number of points of a pulse's own grid in its file."""
    from ..core.h5io import check_pulse_group, open_h5
    with open_h5(path) as h5:
        return check_pulse_group(h5["pulses"][label], path).n_points


def _level0(pulse, params, gmap, n0, creep=0):
    """Level 0: the pulse re-solved on ``gmap(n0)``; (pulse, '') or (pulse, why) on failure."""
    sol = mapped_pulse(params, pulse, gmap, n0, creep=creep)
    if not sol.stats.converged:
        return pulse, (f"steady re-solve on the mapped grid (N = {n0}) did not converge: "
                       f"{sol.stats.message}")
    return sol.to_pulse(), ""


def _clip_failed_above(prev, n_own, source, levels):
    """Whether level 0 goes straight to the pulse's own N: the neighbour tracked from (tracking
    state `prev`, its ladder {N: s L/c_p}) had the same own N and its ladder started there, so
    the clip failed on it (or was not asked for), and this pulse's own N can carry the levels.
    Down the family the pulses get longer, so a clip that failed above fails here as well: a
    deep pulse then skips a re-solve that would give up after :data:`LEVEL0_CREEP` iterations
    (4–6 s at N = 2828, measured at L = 3.3 km; BENCHMARKS.md "Stop 39"), and neighbouring
    pulses keep one ladder. (A worker tracking up the family from its deepest pulse,
    ``run_spectrum(workers=2)``, applies the same rule with the neighbour below.)"""
    ladder = prev[2] if prev is not None and len(prev) > 2 else None
    if not ladder or min(ladder) != int(n_own):
        return False
    try:
        check_refinable(source, levels, level0_points=n_own)
    except UsageError:
        return False
    return True


#: Largest ratio of τ_d steps, (this pulse − the neighbour)/(the neighbour − the one before it),
#: over which :func:`_predicted_ladder` extrapolates; beyond it the neighbour's values are used.
EXTRAPOLATE_RATIO = 2.0


def _predicted_ladder(prev, tau):
    """{N: s L/c_p} expected at τ_d/τ_min = `tau` from the tracking state `prev`: the
    neighbour's ladder, extrapolated linearly in τ_d through the ladder of the pulse tracked
    before it wherever that has the same level (and the two τ_d steps go the same way, the new
    one at most EXTRAPOLATE_RATIO times the old). Newton's start at each level: the deep
    pulses' rates change by ≈ 1 % of s from one pulse to the next, as much as the step
    criterion (1e−6 c/L against s ≈ 1e−4 c/L), so a start at the neighbour's value often costs
    a second assembly of M(σ) that the extrapolated start saves (stop 40)."""
    ladder = prev[2] if prev is not None and len(prev) > 2 else {}
    if not ladder or len(prev) < 5 or prev[4] is None:
        return dict(ladder)
    t1 = prev[3]
    t2, older = prev[4]
    step, before = tau - t1, t1 - t2
    if before == 0.0 or not 0.0 < step / before <= EXTRAPOLATE_RATIO:
        return dict(ladder)
    w = step / before
    return {n: v + w * (v - older[n]) if n in older else v for n, v in ladder.items()}


def _moved_mode(x, x_prev, V_prev):
    """The neighbour's mode V₁(ξ/L) moved onto this pulse's ξ/L: cubic spline inside its range,
    its end values outside (where the mode has decayed). Cubic, not linear: Newton's first step
    from it lands nearer, measured on the clipped pulses at L = 2.3 km (N = 2828) two to four
    assemblies at level 0 with the linear one (stop 39)."""
    from scipy.interpolate import CubicSpline
    xc = np.clip(x, x_prev[0], x_prev[-1])
    V_prev = np.asarray(V_prev)
    return CubicSpline(x_prev, V_prev.real)(xc) + 1j * CubicSpline(x_prev, V_prev.imag)(xc)


def _track(stored):
    """(σ array, c/L) and (ξ/L, V₁ of the leading mode) of a stored spectrum, for tracking."""
    prev = (stored["sigma"], float(stored["rate_unit_c_over_L"]), _stored_ladder(stored))
    mode = None
    if stored["sigma"].size and stored["V"].shape[0]:
        mode = (np.asarray(stored["xi"], float) / float(stored["L"]), stored["V"][0])
    return prev, mode


def _ladder(n_points, s_per_L):
    """{N_k: s_k L_k/c_k}: a pulse's refinement levels, the tracking's start for the same level
    of the next pulse (:func:`refine_leading`'s ``neighbour``)."""
    return {int(k): float(v) for k, v in zip(n_points, s_per_L)}


def _stored_ladder(stored):
    """:func:`_ladder` of a stored spectrum (empty where it has no levels)."""
    if not all(k in stored for k in ("refine_n_points", "refine_s_levels",
                                     "refine_rate_unit_levels")):
        return {}
    return _ladder(np.atleast_1d(stored["refine_n_points"]),
                   np.atleast_1d(stored["refine_s_levels"])
                   / np.atleast_1d(stored["refine_rate_unit_levels"]))


def _seed(path, chosen):
    """Tracking state from the nearest pulse above chosen[0] with a stored converged spectrum
    that has an eigenvalue; (None, None) if there is none."""
    if not chosen:
        return None, None
    every, _ = check_family_file(path)
    if chosen[0] not in every:
        return None, None
    for lab in reversed(every[:every.index(chosen[0])]):
        stored = read_spectrum(path, lab)
        if stored is not None and stored.get("status") == "converged" and stored["sigma"].size:
            return _track(stored)
    return None, None


def _failed(label, pulse, message):
    """A PulseSpectrum that stores the failure and no eigenvalue."""
    return PulseSpectrum(label, np.zeros(0, complex), [], np.zeros(2), float("nan"),
                         pulse.c_p / pulse.L, int(pulse.n_points), "failed", message, 0.0)


def _pulse_result(lab, pulse, params, prev, prev_mode, o, level_progress=None):
    """The spectrum of one pulse (read from its file), tracked from (prev, prev_mode): level 0,
    the eigenvalues, the refinement and the count of the options ``o`` (a dict of
    :func:`run_spectrum`'s settings). No file is written but the count's checkpoint. Returns
    (res, prev, prev_mode), the tracking state after it (unchanged where the pulse failed)."""
    levels, level0_points = o["levels"], o["level0_points"]
    if levels:
        check_refinable(pulse, levels, o["min_points"], level0_points, o["max_points"])
    pulse = source = order4_pulse(pulse, params)
    n0 = level0_size(pulse.n_points, o["min_points"], level0_points, o["max_points"])
    gmap = why = None
    if levels or n0 != pulse.n_points:
        gmap = GridMap(pulse.xi)
        n_own = int(source.n_points)
        fallback = level0_points is None and n0 < n_own
        if fallback and _clip_failed_above(prev, n_own, source, levels):
            # own N first, giving up when it creeps; then the clip (at 6.3-6.6 km the own N
            # fails where the clip holds); then without the creep stop, the own N (td1.008428,
            # 6.0 km, and td1.008393, 6.68 km, converge only so; stop 39 and 40) and last the
            # clip (td1.008397, 6.57 km: converges so in 27 iterations, where the own N does
            # not in 60). Not the clip before the own N: at td1.008393 the clip's level 0 has a
            # spurious real eigenvalue at 1.9e-6 c/L, and its ladder fails (stop 40)
            pulse, why = _level0(source, params, gmap, n_own, LEVEL0_CREEP)
            attempts = ((n0, LEVEL0_CREEP, f"on the clipped N = {n0}"),
                        (n_own, 0, "on the own N without the creep stop"),
                        (n0, 0, f"on the clipped N = {n0} without the creep stop"))
            for n_try, creep, where in attempts if why else ():
                got, why_try = _level0(source, params, gmap, n_try, creep)
                if not why_try:
                    pulse, why = got, ""
                    if n_try == n0:
                        levels = clipped_levels(levels, n0, n_own)
                    break
                why += f"; {where}: {why_try}"
            fallback = False
        else:
            pulse, why = _level0(pulse, params, gmap, n0, LEVEL0_CREEP if fallback else 0)
            if not why:
                levels = clipped_levels(levels, n0, n_own)
        if why and fallback:
            # the clip to max_points is too coarse for this pulse (the deep pulses beyond
            # L ≈ 2.5 km need their own N = 3542): level 0 on the pulse's own N instead
            try:
                check_refinable(source, levels, level0_points=n_own)
            except UsageError as exc:
                why += f"; on its own N instead: {exc}"
            else:
                pulse, why_own = _level0(source, params, gmap, n_own)
                why = f"{why}; on the pulse's own N = {n_own} too: {why_own}" if why_own else ""
    if why:
        return _failed(lab, pulse, why), prev, prev_mode
    unit = pulse.c_p / pulse.L
    guesses, modes = [], None
    predicted = _predicted_ladder(prev, float(pulse.tau_d_ratio))
    if prev is not None and prev[0].size:
        s0 = prev[0][0]
        guesses = [complex(s0.real, abs(s0.imag)) * unit / prev[1]]
        if s0.imag == 0.0 and int(pulse.n_points) in predicted:
            guesses = [complex(predicted[int(pulse.n_points)]) * unit]
        if prev_mode is not None:
            modes = [_moved_mode(pulse.xi / pulse.L, *prev_mode)]
    pin = o["pin_translation"]
    res = pulse_spectrum(pulse, params, guesses=guesses, extra=o["extra"], tol=o["tol"],
                         label=lab, guess_modes=modes, pin_translation=pin)
    if res.status == "converged" and res.sigmas.size and levels:
        res.refined = refine_leading(pulse, params, res, gmap, levels, tol=o["tol"],
                                     progress=level_progress, target=o["target"],
                                     pin_translation=pin, source=source,
                                     rel_target=o["rel_target"],
                                     neighbour=predicted or None)
        if res.refined.status != "converged":
            res.status = "failed"
            res.message = f"refinement failed: {res.refined.message}"
    box0 = o["count_box"]
    if res.status == "converged" and box0 is not None:
        lead = res.leading.real / res.rate_unit if res.sigmas.size else 0.0
        box = (box0[0], max(box0[1], 1.5 * lead), max(box0[2], 1.5 * lead))
        ckpt = count_checkpoint_path(o["path"], lab)
        res.count = count_unstable(res.operator, box, max_evals=o["count_evals"],
                                   workers=o["count_workers"],
                                   threads_per_worker=o["count_threads"],
                                   progress=(lambda k: level_progress(f"count: {k} det"))
                                   if level_progress else None, checkpoint=ckpt)
        if res.count.status == "converged":
            if os.path.exists(ckpt):
                os.remove(ckpt)
        elif os.path.exists(ckpt):
            res.count.message += (f"; its evaluations are kept in {ckpt}: the same count "
                                  "with a larger budget goes on from them")
    res.operator = None                             # N×N matrices: not kept per pulse
    if res.status != "converged":                   # a failure stores no eigenvalue
        res.sigmas = np.zeros(0, complex)
        res.modes = []
        return res, prev, prev_mode
    ref = res.refined
    older = (prev[3], prev[2]) if prev is not None and len(prev) > 3 and prev[2] else None
    prev = (res.sigmas, res.rate_unit,
            _ladder(ref.n_points, ref.s_per_L_levels) if ref is not None else {},
            float(pulse.tau_d_ratio), older)
    prev_mode = (pulse.xi / pulse.L, res.modes[0]["V"]) if res.modes else None
    return res, prev, prev_mode


def claim(counter, step):
    """The next index of a run shared by two workers, one taking it from the top (step +1), the
    other from the bottom (step −1); None once they have met. `counter` holds [next from the
    top, next from the bottom] (a multiprocessing Array with its lock, or a list)."""
    lock = counter.get_lock() if hasattr(counter, "get_lock") else contextlib.nullcontext()
    with lock:
        lo, hi = counter[0], counter[1]
        if lo > hi:
            return None
        if step > 0:
            counter[0] = lo + 1
            return lo
        counter[1] = hi - 1
        return hi


def _chunk_worker(items, params, seed, opts, queue, counter=None, step=1):
    """A worker of :func:`run_spectrum` with ``workers`` > 1: the pulses ``items`` ((label,
    pulse) in order), tracked from ``seed``; each result is put on ``queue`` as (label,
    PulseSpectrum, ''), or the error that stopped it as (label, None, (is a UsageError, text)).
    With a shared `counter` (:func:`claim`) it takes the pulses one at a time from the top
    (step +1) or from the bottom (step −1) of `items` until it meets its partner, tracking
    along its own direction; without, all of them in order."""
    from ..core.memory import keep_freed_memory
    keep_freed_memory()          # as the command's own process (fewer page faults; stop 40)
    prev, prev_mode = seed
    order = iter(range(len(items))) if counter is None else \
        iter(lambda: claim(counter, step), None)
    parent = os.getppid()
    for k in order:
        if os.getppid() != parent:
            # the parent is gone (killed: its `finally` did not run, and a daemonic child
            # outlives a SIGKILL or SIGTERM of its parent): stop instead of computing on for
            # nobody (measured, stop 39: two orphans computed on after `kill` of the command)
            return
        lab, pulse = items[k]
        try:
            res, prev, prev_mode = _pulse_result(lab, pulse, params, prev, prev_mode, opts)
        except UsageError as exc:                    # bad input: the parent's one-line error
            queue.put((lab, None, (True, str(exc))))
            return
        except Exception as exc:                     # reported by the parent, which stops
            import traceback
            queue.put((lab, None, (False, f"{type(exc).__name__}: {exc}\n"
                                          f"{traceback.format_exc()}")))
            return
        queue.put((lab, res, ""))


def split_chunks(labels, workers):
    """`labels` (in order) cut into at most `workers` contiguous runs of near-equal length: each
    worker tracks along its own run."""
    k = max(1, min(int(workers), len(labels)))
    edges = np.linspace(0, len(labels), k + 1).round().astype(int)
    return [labels[a:b] for a, b in zip(edges, edges[1:]) if b > a]


def run_spectrum(path, labels=None, overwrite=False, extra=True, tol=NEWTON_TOL, progress=None,
                 levels=DEFAULT_LEVELS, count_box=None, level_progress=None,
                 min_points=MIN_SPECTRUM_POINTS, target=DEFAULT_TARGET, pin_translation=True,
                 level0_points=None, count_evals=COUNT_EVALS, rel_target=DEFAULT_REL_TARGET,
                 count_workers=1, count_threads=1, guess=None,
                 max_points=MAX_SPECTRUM_POINTS, workers=1, threads=1):
    """Spectrum of every (or each named) converged pulse of `path`, stored in its group.

    Pulses are taken by decreasing τ_d; each starts from its neighbour's eigenvalues at equal
    σL/c (tracking), else from the default shifts. A stored converged spectrum with the same
    settings is kept (resume) unless `overwrite`. A failed eigen-solve stores its status and
    message and no eigenvalues. progress(label, result or None, stored dict or None).

    levels : levels above level 0 for the leading eigenvalue's error estimate
        (:func:`slippulse.stability.refine.refine_leading`: grids of N_0 √2^k points sampled from
        one smooth map of the pulse's grid, :class:`slippulse.steady.grid.GridMap`); a level
        that fails marks the pulse failed and stores no eigenvalue. 0 skips the estimate (no s,
        s_err stored).
    count_box : (x0, x1, y1) in c_p/L, or None: also count the eigenvalues in that box by the
        argument principle (:func:`slippulse.stability.count.count_unstable`), on the pulse's grid.
        x1 and y1 are raised to 1.5 times the leading s L/c_p where that is larger. Its
        evaluations are kept in :func:`count_checkpoint_path` as it goes and read back by a
        rerun on the same operator (an interrupted or out-of-budget count goes on from them);
        the file is removed once the count converges.
    level_progress : callable(str) or None, told about each refinement level / count evaluation.
    target, rel_target : the goal s_err L/c_p <= max(target, rel_target |s L/c_p|); levels
        are added beyond `levels` until it is met (or the next level would exceed
        :data:`slippulse.stability.refine.MAX_LADDER_POINTS`; then the pulse keeps its estimate
        and ``refine_target_met`` = 0). target None: the fixed `levels`.
    min_points, max_points : level 0 has N_0 = N clipped to [min_points, max_points] points
        (the steady equations re-solved on the map; with levels = 0 and N inside, the pulse's
        own grid); a re-solve that fails marks the pulse failed. max_points None: no bound.
    pin_translation : solve with translation pinned (default; docs/spectrum.md §5).
    count_evals : budget of determinant evaluations of the count (reported failed beyond it).
    guess : s L/c_p (> 0) to start the first chosen pulse's search from, instead of the
        spectrum stored above it: a deep pulse (rates below the search's MIN_RE c_p/L) with no
        computed spectrum above. The pulses after it track from it as usual.
    count_workers, count_threads : worker processes of the count and threads of each
        (:func:`count_unstable`'s ``workers``, ``threads_per_worker``).
    level0_points : level 0 has exactly this many points on the map, fewer than the pulse's
        own N included (overrides `min_points`); with `pin_translation` the deep pulses need
        no more than the shallow ones (docs/spectrum.md §5).
    workers, threads : with workers > 1, the pulses to compute are cut into ⌈workers/2⌉
        contiguous runs of near-equal length (:func:`split_chunks`), each served by two
        spawned processes (one for the last run where `workers` is odd) with `threads`
        BLAS/OpenMP/numba threads: one takes its pulses from the top, tracking down, the other
        from the bottom, tracking up, one pulse at a time (:func:`claim`), until they meet, so
        that their work balances whatever each pulse costs. This process writes each result as
        it arrives. The worker from the top of the first run starts as with one worker; the
        others from the default search, which below MIN_RE c/L finds the leading real
        eigenvalue by the sign of det M (:data:`slippulse.stability.spectrum.SCAN_LO`), at the
        cost of a few assemblies. Where they meet depends on the timing, and a pulse's Newton
        starts (and, near where a clip to `max_points` starts failing, its ladder) on which of
        the two reached it: the values agree within Newton's tolerance, the ladders within
        their bars. Not with ``count_workers`` > 1 (no pools inside the workers).
    """
    from ..core.h5io import read_pulse
    t0 = time.perf_counter()
    chosen, params = check_family_file(path, labels)
    settings = {"tol": tol, "extra": int(bool(extra)), "min_re_c_over_L": MIN_RE,
                "levels": int(levels), "count": int(count_box is not None),
                "min_points": int(min_points), "ladder": "smooth map, ratio sqrt(2)",
                "target": -1.0 if target is None else float(target),   # -1: none
                "rel_target": 0.0 if target is None else float(rel_target),
                "max_points": int(max_points or 0),                      # 0: no bound
                "pin_translation": int(bool(pin_translation)),
                "level0_points": int(level0_points or 0)}                # 0: N clipped
    unset = {"pin_translation": 0, "level0_points": 0, "rel_target": 0.0,
             "max_points": 0}                    # settings added later: value before
    # (a spectrum stored before pinning existed was computed without it)
    opts = {"levels": levels, "min_points": min_points, "level0_points": level0_points,
            "max_points": max_points, "extra": extra, "tol": tol,
            "pin_translation": pin_translation, "target": target, "rel_target": rel_target,
            "count_box": count_box, "count_evals": count_evals, "count_workers": count_workers,
            "count_threads": count_threads, "path": str(path)}
    rep = SpectrumReport()
    # tracking starts from the nearest pulse above the first one that has a stored spectrum
    # (any settings): the deep pulses' rates are below the default search's MIN_RE
    prev, prev_mode = _seed(path, chosen)
    if guess is not None:
        prev, prev_mode = (np.array([complex(guess)]), 1.0), None

    def record(lab, res):
        write_spectrum(path, res, settings)
        rep.results.append(res)
        if res.status != "converged":
            rep.failed.append(lab)
        if progress:
            progress(lab, res, None)

    plan = []                                        # (label, stored spectrum to keep or None)
    for lab in chosen:
        stored = None if overwrite else read_spectrum(path, lab)
        keep = stored is not None and stored.get("status") == "converged" and all(
            stored.get(f"setting_{k}", unset.get(k)) == v for k, v in settings.items()) \
            and not short_clipped_ladder(stored, _own_points(path, lab), levels)
        plan.append((lab, stored if keep else None))
    todo = [lab for lab, kept in plan if kept is None]
    if int(workers) > 1 and len(todo) > 1:
        seeds = {}                                   # chunk start: the nearest kept one above
        state = (prev, prev_mode)
        for lab, kept in plan:
            if kept is not None:
                rep.skipped.append(lab)
                if progress:
                    progress(lab, None, kept)
                state = _track(kept)
            else:
                seeds.setdefault(lab, state)
                state = (None, None)
        _run_parallel(path, todo, params, seeds, opts, int(workers), int(threads), record)
    else:
        for lab, kept in plan:
            if kept is not None:
                rep.skipped.append(lab)
                prev, prev_mode = _track(kept)
                if progress:
                    progress(lab, None, kept)
                continue
            pulse, _ = read_pulse(path, lab)
            res, prev, prev_mode = _pulse_result(lab, pulse, params, prev, prev_mode, opts,
                                                 level_progress)
            record(lab, res)
    rep.wall_time = time.perf_counter() - t0
    return rep


#: Seconds between the parent's checks that its workers are alive (a worker that dies without
#: reporting, e.g. killed for memory, stops the run instead of hanging it).
POLL_SECONDS = 5.0


def _run_parallel(path, todo, params, seeds, opts, workers, threads, record):
    """:func:`run_spectrum`'s pulses `todo` on `workers` spawned processes (see there); a run
    starting at `label` tracks from ``seeds[label]``: the kept spectrum right above it, the guess
    or the stored spectrum above the first, or nothing."""
    import multiprocessing
    import queue as queue_mod
    import signal
    import threading

    from ..core.h5io import read_pulse
    from .count import _thread_env
    # runs of near-equal length, each served by two workers from both ends (one for the last
    # run where `workers` is odd): they meet where their work balances, whatever each pulse
    # costs (a deep pulse 3–6 times a shallow one; on the 271-pulse family a static cut by
    # count would leave one worker ≈ 10 % longer than the other, a cost model in N ≈ 35 %,
    # estimated from the per-pulse times of stop 39)
    runs = split_chunks(todo, (workers + 1) // 2)
    ctx = multiprocessing.get_context("spawn")
    q = ctx.Queue()
    procs = []
    # the workers ignore Ctrl-C (an ignored signal stays ignored in the spawned interpreter):
    # this process takes it, says "interrupted" and terminates them
    main = threading.current_thread() is threading.main_thread()
    old_int = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
    try:
        with _thread_env(threads):
            left_workers = workers
            for run in runs:
                items = [(lab, read_pulse(path, lab)[0]) for lab in run]
                counter = ctx.Array("i", [0, len(items) - 1])
                # from the top: tracked from the kept spectrum above (or the guess); from the
                # bottom: from the search alone
                ends = [(1, seeds.get(run[0], (None, None)))]
                if left_workers >= 2 and len(items) > 1:
                    ends.append((-1, (None, None)))
                for step, start in ends:
                    p = ctx.Process(target=_chunk_worker,
                                    args=(items, params, start, opts, q, counter, step),
                                    daemon=True)
                    p.start()
                    procs.append(p)
                left_workers -= len(ends)
    finally:
        if main:
            signal.signal(signal.SIGINT, old_int)
    left = len(todo)
    try:
        while left:
            try:
                lab, res, err = q.get(timeout=POLL_SECONDS)
            except queue_mod.Empty:
                if not any(p.is_alive() for p in procs) and q.empty():
                    raise RuntimeError(f"the spectrum workers stopped with {left} pulse(s) not "
                                       "reported (exit codes "
                                       f"{[p.exitcode for p in procs]})") from None
                continue
            if res is None:
                usage, text = err
                if usage:
                    raise UsageError(text)
                raise RuntimeError(f"spectrum worker failed at {lab}: {text}")
            record(lab, res)
            left -= 1
    finally:
        for p in procs:
            if p.is_alive():
                p.terminate()
            p.join()
