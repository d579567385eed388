"""The deformed grid's zone about the healing front kept on the front's steep drop
(``block_offset``, ``recentre``; docs/steady.md §3)."""
import math

import numpy as np
import pytest

from slippulse.steady.continuation.gridcheck import as_both
from slippulse.steady.continuation.relay import recentre
from slippulse.steady.continuation.stretch import block_offset, stretch_grid
from slippulse.steady.measures import pulse_length
from slippulse.steady.solver import interpolate


def test_block_offset_is_the_fine_cells_centre_minus_the_drops():
    """A grid with a patch of fine cells centred at +30 m and a tanh drop of ln v centred at 0:
    the offset is +30 m (to the resolution of the weights); moving the drop moves it back."""
    coarse = np.linspace(-500.0, 500.0, 1001)                      # h = 1 m
    patch = np.linspace(10.0, 50.0, 801)                           # h = 0.05 m, centre +30 m
    xi = np.unique(np.concatenate([coarse[(coarse < 10) | (coarse > 50)], patch]))
    for drop in (0.0, 12.0):
        y = -10.0 + 5.0 * np.tanh((xi - drop) / 2.0)
        off = block_offset(xi, y, 0.0, 200.0)
        assert off == pytest.approx(30.0 - drop, abs=0.5)
    assert block_offset(xi, np.zeros_like(xi), 0.0, 200.0) == 0.0    # no drop: no offset


def test_recentre_puts_the_fine_cells_back_on_the_drop(params, pulse12):
    """The 1.2 τ_min pulse (L ≈ 1.07 m) re-solved on its grid with the cells of a patch 1–3 % of
    L ahead of its healing front split in 4 (the fine cells a deformed march leaves off the drop,
    made here directly): recentre moves the zone about the front so that the patch sits on the
    drop, re-solves on the normal line, and the pulse is the same to far below the grid
    criterion, on as many nodes with the same pin."""
    from slippulse.steady.continuation.arclength import ArclengthProblem, family_tangent
    from slippulse.steady.continuation.homotopy import solve_robust
    from slippulse.steady.equations import SteadyProblem
    from slippulse.steady.solver import SteadySolution
    sol = as_both(params, pulse12)
    xi, y = sol.xi, np.asarray(sol.x[:-2])
    L = sol.to_pulse().L
    x_back = pulse_length(xi, np.exp(y), params.v_star)[1]
    assert block_offset(xi, y, x_back, 0.05 * L) == 0.0       # uniform cells there: nothing
    cells = (xi[:-1] >= x_back + 0.01 * L) & (xi[1:] <= x_back + 0.03 * L)
    xd = np.sort(np.concatenate([xi] + [xi[:-1][cells] + j / 4 * np.diff(xi)[cells]
                                        for j in (1, 2, 3)]))
    q, beta = float(sol.x[-1]), float(sol.x[-2])
    yd = interpolate(xi, y, xd, params.v_stick(q * params.tau_min))
    n = family_tangent(sol.problem, sol.x, (1.0, 0.0, 1.0))
    pin = int(np.searchsorted(xd, xi[sol.problem.pin_index]))
    base = SteadyProblem(params, q, xd, pin, float(yd[pin]), free="both")
    arc = ArclengthProblem(base, math.log(1 - beta), q, -n[-2] / (1 - beta), n[-1], 1.0, 0.0)
    xs, st = solve_robust(arc, np.concatenate([yd, [beta, q]]), stages=4, max_iter=15)
    assert st.converged
    patched = SteadySolution(base, xs, st, 0.0, 1)
    off_p = block_offset(xd, xs[:-2], pulse_length(xd, np.exp(xs[:-2]), params.v_star)[1],
                         0.05 * L)
    assert 0.01 * L < off_p < 0.04 * L                         # the patch ahead of the drop
    new, dbeta, dL_rel, off, msg = recentre(params, patched)
    assert new is not None, msg
    assert off == pytest.approx(off_p)
    yn = new.x[:-2]
    off_n = block_offset(new.xi, yn, pulse_length(new.xi, np.exp(yn), params.v_star)[1],
                         0.05 * new.to_pulse().L)
    assert abs(off_n) < 0.1 * off_p
    assert new.xi.size == xd.size and new.problem.pin_index == pin
    assert abs(dbeta) < 1e-6 and abs(dL_rel) < 1e-4
    assert abs(new.to_pulse().L / L - 1) < 1e-3
