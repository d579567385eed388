"""A new grid where the deformed grid's arclength corrector stalls, for
:class:`~slippulse.steady.continuation.driver.Continuation`'s fallback (``StretchGrid.relay``).

Measured at the stall of the 271-pulse family (L = 6744 m, N = 3542, docs/analysis.md): the
corrector's Newton creeps at the healing front (the largest residual and the largest correction,
+0.5 to +1.2 in ln v, on the ~10 nodes of its steep drop, cells of 0.38–0.5 m): each step has to
move the front relative to its nodes, and ds = 0.0002 needs 42 iterations (25 allowed). With the
healing zone's cells halved, 10; with only the 65 cells of the steep drop split in 4, 7. The pulse
there is not grid-converged either (its nested check: ΔL/L = 4.7e−4). Hence :func:`refine_front`:
the pulse re-solved on its own grid with the cells of the healing front's steep drop subdivided
(nested: the grid check's 2N − 1 refinement then refines the same family of grids); split in 4
there it passes its check (3.5e−5), split in 2 its re-solve did not converge (homotopy stage 4/4,
max|r| = 1.7e−6). :func:`relay_pulse` (a freshly adapted grid) is the other way measured there;
its pulse could not be grid-checked (below).
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..measures import pulse_length
from ..solver import GridSpec, SteadySolution, interpolate
from .stretch import block_offset, stretch_grid
from .gridcheck import change_at_fixed_tau_d, grid_change, normal_line
from .homotopy import solve_robust


def front_cells(sol: SteadySolution, L: float, frac: float = 0.02, margin: int = 4):
    """Boolean mask over the cells of ``sol``'s grid: the healing front's steep drop, the cells
    within (−1.1 L, −0.9 L] of the pin whose change of ln v is at least ``frac`` of the largest
    there, widened by ``margin`` cells on either side."""
    xi = sol.xi
    y = np.asarray(sol.x[:sol.problem.n], float)
    xf = xi[sol.problem.pin_index]
    mid = 0.5 * (xi[1:] + xi[:-1])
    zone = (mid > xf - 1.1 * L) & (mid <= xf - 0.9 * L)
    dy = np.where(zone, np.abs(np.diff(y)), 0.0)
    sel = dy >= frac * dy.max()
    idx = np.nonzero(sel)[0]
    if idx.size:
        lo, hi = max(idx.min() - margin, 0), min(idx.max() + margin, sel.size - 1)
        sel[lo:hi + 1] = True
    return sel


def refine_front(params, sol: SteadySolution, levels: int = 1, stages: int = 4,
                 max_iter: int = 15, frac: float = 0.02, margin: int = 4):
    """``sol`` (x = (y, β, q)) re-solved with each cell of the healing front's steep drop
    (:func:`front_cells`) split into 2**levels equal cells, on the line through it normal to the
    family tangent, with the residual homotopy (``stages``). The other nodes, the pin and its
    value are kept.

    Returns (refined SteadySolution or None when the re-solve does not converge, Δβ, ΔL/L,
    message): Δβ and ΔL/L the signed change from ``sol`` at fixed τ_d (as a grid check reads it).
    The refined pulse is not checked here: the caller grid-checks it before it writes it or
    marches on from it.
    """
    q = float(sol.x[-1])
    xi = sol.xi
    cells = front_cells(sol, sol.to_pulse().L, frac, margin)
    k = 2 ** int(levels)
    extra = [xi[:-1][cells] + (j / k) * np.diff(xi)[cells] for j in range(1, k)]
    xn = np.sort(np.concatenate([xi] + extra))
    yn = interpolate(xi, sol.x[:-2], xn, params.v_stick(q * params.tau_min))
    pin = int(np.searchsorted(xn, xi[sol.problem.pin_index]))
    fine, dbeta, dL_rel = _resolve_normal(params, sol, xn, yn, pin, sol.problem.y_pin, stages,
                                          max_iter)
    what = (f"healing front refined ({int(cells.sum())} cells split in {k}, N {xi.size} -> "
            f"{xn.size})")
    if not math.isfinite(dbeta):
        return None, math.inf, math.inf, (f"{what}: the re-solve did not converge "
                                          f"({fine.stats.message})")
    return fine, dbeta, dL_rel, (f"{what}: {fine.stats.iterations} it., change at fixed tau_d "
                                 f"dbeta={dbeta:.1e} dL/L={dL_rel:.1e}")


def _resolve_normal(params, sol: SteadySolution, xn, yn, pin, y_pin, stages, max_iter):
    """``sol`` (x = (y, β, q)) re-solved on the grid ``xn`` from ln v = ``yn`` there (pin node
    ``pin`` held at ``y_pin``), on the line through it normal to its family tangent, with the
    residual homotopy of ``stages`` stages. Returns (SteadySolution, Δβ, ΔL/L at fixed τ_d);
    Δ = inf when the re-solve does not converge (the solution's stats say why)."""
    n, base, arc = normal_line(params, sol, xn, pin, y_pin)
    t0 = time.perf_counter()
    xs, st = solve_robust(arc, np.concatenate([yn, sol.x[-2:]]), stages=stages,
                          max_iter=max_iter, reuse=True)
    new = SteadySolution(base, xs, st, time.perf_counter() - t0, 1)
    if not st.converged or n[-1] == 0.0:
        return new, math.inf, math.inf
    return (new, *change_at_fixed_tau_d(params, sol, n, new))


def zone_offset(params, sol: SteadySolution, back_zone: float = 0.05):
    """(offset, x_back): :func:`~.stretch.block_offset` of ``sol``'s grid about its back
    half-maximum crossing x_back (the zone ± ``back_zone`` · L). Raises ValueError where ln v
    has no such crossing (:func:`~slippulse.steady.measures.pulse_length`)."""
    y = np.asarray(sol.x[:-2], float)
    L, x_back, _ = pulse_length(sol.xi, np.exp(y), params.v_star)
    return block_offset(sol.xi, y, x_back, back_zone * L), x_back


def relay_pulse(params, sol: SteadySolution, n_points: int, spec: GridSpec = GridSpec(),
                stages: int = 4, max_iter: int = 15):
    """``sol`` (x = (y, β, q), on a deformed grid) re-solved on a grid of ``n_points`` adapted to
    it (rounded down to even: :func:`grid_change` lays out 2 × ``n_points // 2``), on the line
    through it normal to the family tangent, with the residual homotopy of ``stages`` stages.

    Returns (re-laid SteadySolution or None when the re-solve does not converge, Δβ, ΔL/L,
    message), as :func:`refine_front`.

    Notes
    -----
    Measured at L = 6.70 km (the 271-pulse family's deepest pulse, N = 3542 deformed): the
    adapted grid of 3542 points converged in 23 s (homotopy) and differs by ΔL/L = −2.0e−3 at
    fixed τ_d, 5009 points −1.2e−3, 7083 points −7.0e−4: the adapted layout converges slowly
    (≈ N^−1.5) toward the deformed grid's pulse, and its healing front refined alone did not
    re-solve (homotopy, 4 stages): its pulse cannot be grid-checked there.
    """
    n_half = int(n_points) // 2
    fine, dbeta, dL_rel = grid_change(params, sol, n_half, spec, max_iter=max_iter, nested=False,
                                      stages=stages)
    st = fine.stats
    if not st.converged or not math.isfinite(dbeta):
        return None, math.inf, math.inf, (f"re-laid grid of {2 * n_half} points: the re-solve "
                                          f"did not converge ({st.message})")
    return fine, dbeta, dL_rel, (f"re-laid grid of {2 * n_half} points: {st.iterations} it., "
                                 f"change at fixed tau_d dbeta={dbeta:.1e} dL/L={dL_rel:.1e}")


def recentre(params, sol: SteadySolution, front_zone: float = 0.01, back_zone: float = 0.05,
             stages: int = 4, max_iter: int = 15, offset=None):
    """``sol`` (x = (y, β, q), on a deformed grid) re-solved on its grid with the zone about the
    healing front moved so that its finest cells sit on the front's steep drop again
    (:func:`~.stretch.block_offset` → 0): :func:`~.stretch.stretch_grid` with the offset as the
    shift (the body between the edges lengthened or shortened by it, node count and order kept),
    ln v interpolated, re-solved on the line through ``sol`` normal to the family tangent with
    the residual homotopy (``stages``). ``offset``: :func:`zone_offset` of ``sol`` when the
    caller has it (offset, x_back).

    Returns (SteadySolution or None when the re-solve does not converge, Δβ, ΔL/L, offset before,
    message), Δβ and ΔL/L the change from ``sol`` at fixed τ_d, as :func:`refine_front`.
    """
    q, L = float(sol.x[-1]), sol.to_pulse().L
    xi, y = sol.xi, np.asarray(sol.x[:-2], float)
    off, x_back = zone_offset(params, sol, back_zone) if offset is None else offset
    xn = stretch_grid(xi, xi[sol.problem.pin_index], off, front_zone * L, x_back, back_zone * L)
    yn = interpolate(xi, y, xn, params.v_stick(q * params.tau_min))
    pin = sol.problem.pin_index
    new, dbeta, dL_rel = _resolve_normal(params, sol, xn, yn, pin, float(yn[pin]), stages,
                                         max_iter)
    what = f"healing-front zone moved by {off:+.2f} m onto its drop (N={xi.size})"
    if not math.isfinite(dbeta):
        return None, math.inf, math.inf, off, (f"{what}: the re-solve did not converge "
                                               f"({new.stats.message})")
    return new, dbeta, dL_rel, off, (f"{what}: {new.stats.iterations} it., change at fixed tau_d "
                                     f"dbeta={dbeta:.1e} dL/L={dL_rel:.1e}")
