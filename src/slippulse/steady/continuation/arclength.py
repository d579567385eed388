"""Pseudo-arclength continuation in (ln(1 − β), τ_d/τ_min): the closed problem, the family
tangent and the settings of the deep march (:mod:`.deep`)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..equations import SteadyProblem
from ..solver import MAX_POINTS
from .tolerance import GRID_TOLERANCE


class ArclengthProblem:
    """The steady equations with both β and q = τ_d/τ_min free, closed by the pseudo-arclength
    condition in the plane (a, q/κ), a = ln(1 − β):

        t_a (a − a_0) + t_Q (q − q_0)/κ − ds = 0,

    (t_a, t_Q) the unit tangent of the family at the last pulse (a_0, q_0). Unknowns (y, β, q);
    the Jacobian is the (N+1)×(N+2) one of ``SteadyProblem(free="both")`` with the row
    (0…0, −t_a/(1 − β), t_Q/κ) appended. Square, so :func:`newton` drives it.
    """

    def __init__(self, base: SteadyProblem, a0, q0, t_a, t_Q, kappa, ds):
        self.base, self.a0, self.q0 = base, a0, q0
        self.t_a, self.t_Q, self.kappa, self.ds = t_a, t_Q, kappa, ds

    def _arc(self, x):
        a = math.log(1.0 - x[-2])
        return self.t_a * (a - self.a0) + self.t_Q * (x[-1] - self.q0) / self.kappa - self.ds

    def valid(self, x):
        return self.base.valid(x)

    def residual(self, x):
        if not self.valid(x):
            return np.full(x.size, np.inf)
        return np.concatenate([self.base.residual(x), [self._arc(x)]])

    def residual_and_jacobian(self, x):
        r, J = self.base.residual_and_jacobian(x)
        row = np.zeros(x.size)
        row[-2] = -self.t_a / (1.0 - x[-2])
        row[-1] = self.t_Q / self.kappa
        return np.concatenate([r, [self._arc(x)]]), np.vstack([J, row])


def family_tangent(prob: SteadyProblem, x, orient):
    """Unit tangent of the solution curve at a converged x = (y, β, q) of ``free="both"``.

    Notes
    -----
    The tangent n spans the null space of the (N+1)×(N+2) Jacobian J: J n = 0. It is found from
    the square system [J; c] n = [0; 1] with c = (0…0, orient) the previous direction in (β, q)
    (so n points the same way along the curve), then scaled to unit length in (a, q/κ):
    n_a = −n_β/(1 − β). Returns n (full vector, in (y, β, q)) scaled so that n_a² + n_Q² = 1 with
    n_Q = n_q/κ, where κ is passed through ``orient = (c_β, c_q, κ)``.
    """
    c_b, c_q, kappa = orient
    _, J = prob.residual_and_jacobian(x)
    A = np.vstack([J, np.zeros(x.size)])
    A[-1, -2], A[-1, -1] = c_b, c_q
    rhs = np.zeros(x.size)
    rhs[-1] = 1.0
    return unit_tangent(np.linalg.solve(A, rhs), x[-2], kappa)


def unit_tangent(n, beta, kappa):
    """n scaled to unit length in (a, q/κ), a = ln(1 − β): n_a = −n_β/(1 − β), n_Q = n_q/κ."""
    return n / math.hypot(-n[-2] / (1.0 - beta), n[-1] / kappa)


def tangent_by_refinement(A, lu, max_iter=30, rtol=1e-11):
    """The solution n of A n = (0…0, 1) by iterative refinement with the LU of a nearby matrix
    (scipy ``lu_factor``): n ← n + LU⁻¹ (e − A n). None when a correction grows, or when they do
    not fall below ``rtol`` ‖n‖ within ``max_iter`` refinements (then solve A directly).

    With A = [J; c], J the (N+1)×(N+2) Jacobian at a converged pulse and c any row with c·n ≠ 0,
    n spans J's null space: the family tangent (:func:`family_tangent` with c = orient). The
    corrector of an arclength step has factored such a matrix at most a few steps back (its last
    row is the arclength condition's), so the tangent costs back-substitutions and products with
    A (N² each) instead of an LU (N³). Each refinement shrinks the error by ‖LU⁻¹(A − A_LU)‖:
    measured ≈ 0.1 with an LU two steps of ds = 0.001 old at 1.2 τ_min (N = 500; 10 refinements
    to 3e−11). ``rtol`` bounds the tangent's relative error; it sets the predictor and the
    arclength condition's direction only, never the tolerance of the pulse.
    """
    e = np.zeros(A.shape[0])
    e[-1] = 1.0
    n = sla.lu_solve(lu, e, check_finite=False)
    last = math.inf
    for _ in range(max_iter):
        dn = sla.lu_solve(lu, e - A @ n, check_finite=False)
        n = n + dn
        size = np.linalg.norm(dn) / np.linalg.norm(n)
        if not (np.isfinite(size) and size < last):
            return None
        if size <= rtol:
            return n
        last = size
    return None



@dataclass
class DeepSettings:
    """Pseudo-arclength continuation of the deep family (near τ_min).

    ds, ds_min, ds_max : arclength step in the plane (ln(1−β), q/κ) and its bounds.
    fine : smallest spacing in τ_d/τ_min between written pulses; an arclength pulse is written when
        its label (4 decimals, so `fine` ≥ 1e-4) is new and it lies ≥ fine/2 from the last one.
    check : re-solve every written pulse at 2N (fixed β; converted to fixed τ_d along the family
        tangent) and double N until |Δβ| ≤ tol_beta and |ΔL|/L ≤ tol_L; the 2N solution is written,
        with the N-vs-2N differences as attributes.
    n_max : largest N tried by the check.
    max_length : stop once L exceeds this (m).
    regrid : a new grid is laid out when L has changed by more than this fraction since the last.
    stretch : instead of laying out new grids, deform the current one every step with
        :func:`stretch_grid` (both edges kept, the body lengthened with L) and keep the nodal
        ln v: no interpolation, so no jump of the discrete family at a regrid (measured with the
        re-laid grids: each regrid moves τ_d/τ_min by ~1e-5 at β ≈ 0.995, comparable to a step).
    front_zone : width of the leading-edge zone kept by :func:`stretch_grid`, in L.
    back_zone : width of the zone about the healing front (the back half-maximum crossing) that
        :func:`stretch_grid` moves rigidly, in L.
    homotopy : stages of the residual homotopy (:func:`solve_robust`) when Newton fails from an
        interpolated guess (grid checks, new grids).
    spacing : the "auto" march (:func:`~slippulse.steady.continuation.family.run_family`) writes,
        and grid-checks, an accepted step only once L has grown by this fraction since the last
        written pulse (0: every accepted step); the pulse the march ends on is always written.
        Deep in the family a step moves L by 0.2-0.4 % and its grid check costs 2-5 steps
        (docs/steady.md), so a spacing of ~1 % takes the march deeper per hour.
    relay : the "auto" march only: where the corrector on the deformed grid fails at ``ds_min``,
        re-solve the current pulse with the cells of its healing front's steep drop split into
        2**``relay_levels`` (:func:`~slippulse.steady.continuation.relay.refine_front`: nested,
        the other nodes kept), grid-check it like every written pulse, write it, and go on
        deforming the refined grid from it; a refined pulse that does not converge or does not
        pass its check ends the march as before (the failed check written failed). Nothing
        changes before the first failure. At most ``relay`` refinements in a run (0: off), and
        none twice without an accepted step between.
    predictor : ``stretch`` only: how the step predicts the deformed grid and ln v on it.
        "tangent": the grid's front zone moved by the change of L along the family tangent, the
        nodal ln v kept (the predictor of stops ≤ 41). "length": moved by the change of L per ds
        of the last accepted step (the tangent's fell ≈ 13 % short at 7.2 km, so the healing
        front landed about a cell off its nodes every step and the corrector crept). "secant"
        (the "auto" march's): "length", and the nodal ln v along the secant through the last two
        pulses, once the last step was itself "length" or "secant" on the same grid (N kept: no
        grid check refinement, front refinement, replace or restart between). Without that
        history each falls back to the one before it (a new march begins with "tangent"; one
        resumed from a file with "length", :meth:`~.deep.DeepMarch.resume_step`). Measured from the 7187 m pulse, 12 steps each (docs/steady.md §8):
        "tangent" 41 m, "length" 194 m, "secant" 251 m of L.
    predictor_ds_max : "length" and "secant" only for steps ds ≤ this (else "tangent"). They were
        measured to help at ds ≤ 0.002 (at 7.2 km; steps of 0.003–0.0045 failed with them); with
        them at every ds, the march from scratch (ds 0.01–0.4 above 1.009 τ_min) failed its large
        steps, halved ds again and again and had written 36 deep pulses by 611 m where the
        tangent had needed 18 to 1.78 km (stop 42). Above it the march is the tangent's.
    creep : > 0: an arclength corrector stops (failed: ds halved) as soon as max|r| has not
        halved over that many Newton iterations (:func:`~slippulse.steady.newton.newton`
        ``creep``); 0: only after ``max_iter``. Measured from the 2550 m seed (stop 44, one
        thread): with ``max_iter`` = 25 a step too long for Newton's basin spent 25 damped
        iterations (≈ 50 s) before it failed, and some converged after 11–17; with creep = 4
        those fail after 5–6 iterations and the halved steps converge in 2–5: 9 steps to
        2860 m in 143 s against 265 s. But over longer runs it held the march at small ds
        (≈ 0.002 at 3.2 km, a failure every third step), where the grid check's ΔL/L rose from
        5e−6 to 9e−5 in 250 m, and the march from scratch reached N = 5374 by 1 km (N = 3542 at
        1.6 km without): not the "auto" march's (stop 44).
    hold : ``stretch`` with the "length" or "secant" predictor: once a step longer than
        ``predictor_ds_max`` (so the tangent's) has failed and the next accepted one, at or below
        it, was the "length" or "secant" predictor's, ds stays ≤ ``predictor_ds_max`` for the rest
        of the march. Without it the step control grows ds by 1.5 after every easy step, deep in
        the family just past the threshold, where the tangent's step fails after ``max_iter``
        iterations (60–100 s at N = 5062): stop 44's march from 4.5 to 4.9 km failed one step
        in three, about half of its wall time (docs/steady.md §8, stop 45).
    reuse_lu : keep the LU the corrector last factored (one Newton iterate from the pulse) and
        find the next family tangent by iterative refinement with it
        (:func:`tangent_by_refinement`: back-substitutions and products with the Jacobian
        instead of an LU); the tangent agrees with the directly solved one to ~1e−11, so the
        march takes the same steps.
    chord : also start each corrector with chord iterations with that LU
        (:func:`~slippulse.steady.newton.chord`) before forming a Jacobian. 2.3× cheaper steps at
        a fixed ds (stop 44, from the 2550 m seed), the same pulses; but the step control reads
        Newton iterations, which chord iterations replace, so ds grows otherwise and the march
        takes another path: from scratch it refined its grid to N = 5397 by 1.14 km (N = 3542
        at 1.59 km on the path of stops 28–42). Off in the "auto" march.
    chord_held : chord iterations as ``chord``, but only once ``hold`` has capped ds (the march's
        ``held``): ds then stays at its cap while steps converge, whatever the iterations, so the
        chord cannot change the path the way it did with ds free. On in the "auto" march
        (stop 45).
    creep_held : ``creep`` (this many iterations), but only once held and at a ds within
        ``cap_shrink`` of the cap (below it, after halvings, the corrector gets ``max_iter``;
        stop 46 blamed creep for a resume whose attempts at 0.00128, 0.00064 and 0.00032
        failed after 4–5 iterations each, but without it they failed after 25 each, stop 47:
        the cause was the ‖r‖₂ line search, ``natural_held``). Held at the cap of
        0.002 at N = 6614 (6.8–7.0 km, stop 46), two steps converged (30–45 s) and the third
        failed after ``max_iter`` = 25 iterations (2.5–3 min), every time: the failures took
        more than half of the march's time. Stop 44 left ``creep`` off because the steps it
        fails early halve ds and held the march at small ds; held, ds is at its cap anyway.
        4 in the "auto" march (stop 46).
    cap_shrink, cap_grow_after : once held, the cap on ds (``DeepMarch.cap``, at first
        ``predictor_ds_max``) becomes ``cap_shrink`` × ds after each failed attempt at a ds of
        at least ``cap_shrink`` × cap (a failure far below it, after halvings, leaves it), and is
        divided by ``cap_shrink`` (up to ``predictor_ds_max``) after ``cap_grow_after`` accepted
        steps at it in a row (1: a fixed cap). Held at 0.002 at N = 6614 (7.0–7.3 km, stop 46) the march
        went 0.002 accepted, 0.002 failed, 0.001, 0.0015, 0.002 accepted, 0.002 failed ...:
        one attempt in three or four failed at the cap. 0.8 and 6 in the "auto" march (stop 46).
    line_search : the corrector's line search (:func:`~slippulse.steady.newton.newton`):
        "residual" (‖r‖₂ must fall) or "natural" (the simplified Newton correction must shrink).
    natural_held : the "natural" line search once ``hold`` has capped ds (the march's ``held``).
        Deep in the family the corrector's Jacobian is nearly singular along the motion of the
        healing front (smallest singular value 1e−6 to 9e−8 against max|J| ≈ 650 at 9.5 km,
        N = 6614): an iterate with max|r| = 6e−6 still lay ‖δ‖₂ ≈ 1 from the pulse (the drop ~0.1 m off),
        the full Newton step raised ‖r‖₂ five-fold, and the ‖r‖₂ test cut every step to
        λ ≤ 1/4 (‖r‖₂ down ≈ 1 %), so max|r| crept 6.0e−6 → 3.8e−6 in 24 iterations and the
        step failed, at ds = 0.00064 and again at 0.00032. With "natural" the same corrector from the same guess took
        full steps and converged in 9 iterations (stop 47, docs/steady.md §8); the stop-40 grid
        check re-solves had the same trouble and the same cure. With ``creep``, the natural
        iteration creeps only when neither max|r| nor ‖δ‖₂ has halved (max|r| rises on its way
        in). On in the "auto" march (stop 47).
    recentre : the "auto" march only (:func:`~slippulse.steady.continuation.family._auto_deep`),
        once ``hold`` has capped ds: at the start and after every written pulse that passed its
        check, where the finest cells of the zone about the healing front lie more than
        ``recentre`` · L from its steep drop (:func:`~.stretch.block_offset`), the zone is moved
        back onto it and the pulse re-solved there (:func:`~.relay.recentre`) before the march
        goes on (0: off). Each step moves the zone by the predicted change of L and the
        corrector moves the front by what that missed, so the drop wanders off the cells laid
        out for it: measured on the march of stops 43–46, the zone's 0.05 m cells lay 17–83 m
        ahead of the back crossing at 6.76 km (offset +57 m), the drop on cells of 0.15–0.31 m
        (|Δ ln v| ≤ 0.32 per cell); moved back, 2 Newton iterations, |Δ ln v| ≤ 0.075 per cell,
        ΔL/L = −4.3e−6 at fixed τ_d (docs/steady.md §8). 0.001 in the "auto" march (stop 46).
    """

    ds: float = 0.1
    ds_min: float = 0.004
    ds_max: float = 0.4
    fine: float = 1e-4
    check: bool = True
    tol_beta: float = GRID_TOLERANCE.beta
    tol_L: float = GRID_TOLERANCE.L
    n_max: int = MAX_POINTS
    max_length: float = math.inf
    max_iter: int = 15
    regrid: float = 0.05
    stretch: bool = False
    front_zone: float = 0.01
    back_zone: float = 0.05
    homotopy: int = 8
    spacing: float = 0.0
    relay: int = 0
    relay_levels: int = 2
    predictor: str = "tangent"
    predictor_ds_max: float = 0.002
    hold: bool = False
    reuse_lu: bool = True
    chord: bool = False
    chord_held: bool = False
    creep: int = 0
    creep_held: int = 0
    cap_shrink: float = 1.0
    cap_grow_after: int = 6
    line_search: str = "residual"
    natural_held: bool = False
    recentre: float = 0.0
