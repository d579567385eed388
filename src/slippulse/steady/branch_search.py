"""Every steady pulse at one τ_d: deflated Newton (:mod:`.deflation`) from a stated set of guesses.

For each guess, in order: Newton on the deflated residual M F on the guess's own grid (N₀ points,
the phase condition on its front), the solutions found so far deflated after being moved onto that
grid with their front on the pin (the problem is pinned, so a known pulse translated elsewhere is
not a root there); a root is then re-solved without deflation on adapted grids to N points
(:func:`~slippulse.steady.solver.solve_pulse`), compared with the known pulses by the deflation
norm on the final grid, kept if new, grid-checked (re-solved at 2N − 1 by nested refinement), and
Newton restarts from the same guess with it deflated too — until the deflated Newton fails. The
norm: ‖e‖² = mean_j (Δ ln v_j)² + (Δβ/β_i)² (the RMS of ln v over the nodes and the relative
speed).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import PchipInterpolator

from .deflation import Deflation, deflated_newton
from .equations import SteadyProblem
from .solver import (count_humps, default_guess, front_pin, interpolate, refine_nested,
                     regrid_guess, solve_pulse)
from .measures import pulse_length

#: Two solutions closer than this in the deflation norm are one (ln v RMS; the grid-converged
#: pulses of one branch on two grids differ by ~1e-4, distinct branches by O(1)).
SAME = 0.05
#: Roots of a guess's grid that refine to a known pulse (its discrete twin there, not removed by
#: deflating the known pulse moved onto the grid) that one guess may meet before it is abandoned.
MAX_SHADOWS = 3


L0_TABLE_I = 0.8835729338221293     # L0 of Table I, m: the guesses' lengths are stated for it


@dataclass(frozen=True)
class Guess:
    """A starting guess: the built-in Freund pulse (:func:`default_guess`) with length L, speed β
    and cohesive length lc (in units of L0), repeated ``humps`` times at spacing ``sep`` (units of
    L0) behind the first, each copy's slip rate excess ``decay`` times the one ahead (a bound
    state); or a stored pulse (``source`` FILE:LABEL)."""
    L_over_L0: float = 0.0
    beta: float = 0.01
    lc_over_L0: float = 0.0
    humps: int = 1
    sep_over_L0: float = 0.0
    decay: float = 0.8
    source: str = ""

    def describe(self, params) -> str:
        if self.source:
            return f"pulse {self.source}"
        text = (f"Freund L={self.L_over_L0 * params.L0:.3g} m beta={self.beta:g} "
                f"lc={self.lc_over_L0 * params.L0 * 1e3:.3g} mm")
        if self.humps > 1:
            text += (f" x{self.humps} at {self.sep_over_L0 * params.L0:.3g} m spacing "
                     f"(amplitude x{self.decay:g} each)")
        return text


def _m(metres):
    return metres / L0_TABLE_I


def basin_guesses():
    """The 27 single-pulse guesses of the measured basin (docs/branches.md §2): L ∈ {0.7, 2, 0.25}
    m, β ∈ {0.01, 0.003, 0.03}, ℓ_c ∈ {5, 1.5, 15} mm for Table I (scaled with L0)."""
    return [Guess(_m(L), b, _m(lc)) for L in (0.7, 2.0, 0.25) for b in (0.01, 0.003, 0.03)
            for lc in (5e-3, 1.5e-3, 15e-3)]


def bound_state_guesses():
    """Two and three built-in pulses (L = 0.7 m, β = 0.01, ℓ_c = 5 mm) at spacings 1, 1.4, 1.8,
    2.5 m (two) and 1.4 m (three)."""
    one = dict(L_over_L0=_m(0.7), beta=0.01, lc_over_L0=_m(5e-3))
    return ([Guess(**one, humps=2, sep_over_L0=_m(s)) for s in (1.4, 1.0, 1.8, 2.5)]
            + [Guess(**one, humps=3, sep_over_L0=_m(1.4))])


GUESS_SETS = {
    "basin": lambda: basin_guesses() + bound_state_guesses(),
    "single": basin_guesses,
    # the built-in guess, and a two-pulse bound state 1.4 m apart
    "quick": lambda: [Guess(_m(0.7), 0.01, _m(5e-3)),
                      Guess(_m(0.7), 0.01, _m(5e-3), humps=2, sep_over_L0=_m(1.4))],
}


@dataclass
class Found:
    """A distinct solution: the pulse (N points), the guess that found it first, its grid check."""
    pulse: object
    guess: int
    check: dict = field(default_factory=dict)


@dataclass
class SearchReport:
    tau_d_ratio: float
    deflation: Deflation
    guesses: list
    found: list
    reached: list          # per guess: list of solution indices it reached (in order)
    attempts: list         # per guess: (message of each deflated solve)
    wall_time: float
    n_points: int
    coarse_points: int


def align(pulse, xi, pin_index, y_pin, v_stick):
    """ln v of ``pulse`` translated so that its leading edge crosses y_pin at xi[pin_index],
    interpolated on ``xi``."""
    x0 = np.asarray(pulse.xi, float)
    y0 = np.log(np.asarray(pulse.v, float))
    k = int(np.argmax(y0))
    ahead = np.nonzero((np.arange(y0.size) > k) & (y0 < y_pin))[0]
    if ahead.size == 0:
        raise ValueError("the known pulse does not fall below the pin level ahead of its maximum")
    j = int(ahead[0])
    t = (y_pin - y0[j - 1]) / (y0[j] - y0[j - 1])
    xc = x0[j - 1] + t * (x0[j] - x0[j - 1])
    return interpolate(x0 + (xi[pin_index] - xc), y0, xi, v_stick)


def _weights(n, beta):
    w = np.full(n + 1, 1.0 / n)
    w[-1] = 1.0 / beta ** 2
    return w


def _start(params, q, guess, n0):
    if guess.source:
        from ..core.h5io import read_pulse
        path, label = guess.source.rsplit(":", 1)
        p, _ = read_pulse(path, label)
        xi, y = regrid_guess(params, q, np.asarray(p.xi, float), np.log(np.asarray(p.v, float)),
                             p.beta, n0)
        return xi, y, p.beta
    L, lc = guess.L_over_L0 * params.L0, guess.lc_over_L0 * params.L0
    if guess.humps == 1:
        return default_guess(params, q, n0, L=L, beta=guess.beta, lc=lc)
    sep = guess.sep_over_L0 * params.L0
    span = L + (guess.humps - 1) * sep
    xi, _, beta = default_guess(params, q, n0, L=span, beta=guess.beta, lc=lc)
    x1, y1, _ = default_guess(params, q, n0, L=L, beta=guess.beta, lc=lc)
    v_st = params.v_stick(q * params.tau_min)
    one = PchipInterpolator(x1, np.exp(y1) - v_st, extrapolate=False)
    v = np.full(xi.size, v_st)
    for j in range(guess.humps):
        u = one(xi + j * sep)
        v += guess.decay ** j * np.where(np.isnan(u), 0.0, u)
    return xi, np.log(v), beta


def distance(pa, pb, params):
    """Deflation-norm distance of two pulses at one τ_d, b moved onto a's grid and pin."""
    xi = np.asarray(pa.xi, float)
    ya = np.log(np.asarray(pa.v, float))
    k, _ = front_pin(xi, ya, math.log(pa.v_stick))
    yb = align(pb, xi, k, float(ya[k]), pa.v_stick)
    return math.sqrt(float(np.mean((ya - yb) ** 2)) + ((pa.beta - pb.beta) / pb.beta) ** 2)


def grid_check(params, pulse):
    """The pulse re-solved at 2N − 1 (nested refinement): dβ, dL/L (None where it failed)."""
    t0 = time.perf_counter()
    fine = refine_nested(params, pulse)
    if not fine.stats.converged:
        return {"passed": False, "message": fine.stats.message,
                "wall": time.perf_counter() - t0}
    pf = fine.to_pulse()
    return {"passed": True, "n_fine": int(pf.n_points), "dbeta": float(pf.beta - pulse.beta),
            "dL_rel": float((pf.L - pulse.L) / pulse.L), "wall": time.perf_counter() - t0}


def search(params, tau_d_ratio, guesses, n_points=1000, coarse_points=500, p=2.0, sigma=1.0,
           tol=1e-12, max_iter=60, max_solutions=8, check=True, progress=None) -> SearchReport:
    """Deflated-Newton search for the distinct pulses at τ_d = tau_d_ratio τ_min (module doc).

    progress : callable(str), optional, told about each attempt.
    """
    params.check_tau_d(tau_d_ratio * params.tau_min)
    t0 = time.perf_counter()
    defl = Deflation(p=p, sigma=sigma)
    found, reached, attempts = [], [], []
    v_st = params.v_stick(tau_d_ratio * params.tau_min)
    for gi, g in enumerate(guesses):
        reached.append([])
        attempts.append([])
        try:
            xi, y, beta = _start(params, tau_d_ratio, g, coarse_points)
        except (RuntimeError, ValueError) as exc:
            attempts[-1].append(f"guess unusable: {exc}")
            continue
        k, _ = front_pin(xi, y, math.log(v_st))
        prob = SteadyProblem(params, tau_d_ratio, xi, k, float(y[k]))
        shadows = []        # roots found on this grid (a known pulse's discrete twin included)
        for _ in range(max_solutions + MAX_SHADOWS):
            if len(found) >= max_solutions:
                break
            # the known solutions, moved onto this grid and pin, and this grid's own roots
            local = Deflation(p=p, sigma=sigma)
            for xs in shadows:
                local.add(xs, _weights(xi.size, float(xs[-1])))
            for f in found:
                try:
                    yk = align(f.pulse, xi, k, float(y[k]), v_st)
                except ValueError:
                    continue
                local.add(np.concatenate([yk, [f.pulse.beta]]), _weights(xi.size, f.pulse.beta))
            res = deflated_newton(prob, np.concatenate([y, [beta]]), local, tol=tol,
                                  max_iter=max_iter)
            if progress:
                progress(f"guess {gi}: {res.message}")
            if not res.converged:
                attempts[-1].append(f"deflated Newton failed: {res.message}")
                break
            sol = solve_pulse(params, tau_d_ratio, n_points=n_points, coarse_points=coarse_points,
                              guess=(xi, res.x[:-1], float(res.x[-1])), passes=2)
            if not sol.stats.converged:
                attempts[-1].append(f"root at beta={res.x[-1]:.6g} did not re-solve at "
                                    f"N={n_points}: {sol.stats.message}")
                break
            shadows.append(res.x.copy())
            pulse = sol.to_pulse()
            same = [i for i, f in enumerate(found) if distance(pulse, f.pulse, params) < SAME]
            if same:
                reached[-1].append(same[0])
                attempts[-1].append(f"re-found solution {same[0]} (its root on this grid, now "
                                    "deflated too)")
                continue
            idx = len(found)
            found.append(Found(pulse, gi, grid_check(params, pulse) if check else {}))
            reached[-1].append(idx)
            attempts[-1].append(f"new solution {idx}: beta={pulse.beta:.8g} L={pulse.L:.5g} m "
                                f"humps={count_humps(pulse.v)}")
    return SearchReport(tau_d_ratio, defl, list(guesses), found, reached, attempts,
                        time.perf_counter() - t0, n_points, coarse_points)
