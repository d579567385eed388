"""Newton steps solved by GMRES on an earlier LU (:class:`KrylovLU`): the same solutions as with
an LU per step, to the solver's tolerance, with fewer LUs; a step GMRES cannot solve falls back
to an LU; the grid check's re-solves and a march's correctors with Krylov steps give the same
pulses and checks."""
import numpy as np
import pytest

from slippulse.steady.continuation import (Continuation, FreeSteps, NewtonCorrector,
                                           SecantPredictor, Strategy, StretchGrid)
from slippulse.steady.continuation.gridcheck import as_both, grid_change
from slippulse.steady.newton import (NEWTON_TOL, DirectLU, KrylovLU, gmres_on_lu, lu_factor,
                                     newton)
from slippulse.steady.solver import solve_pulse


def test_gmres_on_a_nearby_lu_solves_to_its_tolerance_or_says_it_cannot():
    """GMRES preconditioned by the LU of a perturbed matrix reaches rtol; with an LU of an
    unrelated matrix and few iterations it returns None (the caller then factors)."""
    rng = np.random.default_rng(1)
    n = 300
    A = rng.standard_normal((n, n)) + 30 * np.eye(n)
    b = rng.standard_normal(n)
    near = lu_factor(A + 0.05 * rng.standard_normal((n, n)))
    x, k = gmres_on_lu(A, b, near, 1e-10, 30)
    assert x is not None and 1 <= k <= 30
    assert np.linalg.norm(b - A @ x) <= 1e-10 * np.linalg.norm(b)
    assert np.allclose(x, np.linalg.solve(A, b), rtol=1e-8, atol=0)
    far = lu_factor(rng.standard_normal((n, n)) + 30 * np.eye(n))
    x, k = gmres_on_lu(A, b, far, 1e-10, 3)
    assert x is None and k == 3


def test_newton_with_krylov_steps_reaches_the_same_solution_with_fewer_lus(params, pulse12):
    """A re-solve at τ_d = 1.19 from the 1.2 pulse: an LU per step, against GMRES on the first
    LU: both converge to NEWTON_TOL at the same pulse (1e-9 in ln v), Krylov with fewer LUs."""
    from slippulse.steady.equations import SteadyProblem
    p = pulse12.problem
    prob = SteadyProblem(params, 1.19, p.xi, p.pin_index, p.y_pin, H=p.H)
    x0 = pulse12.x.copy()
    xd, sd = newton(prob, x0, linear=DirectLU())
    xk, sk = newton(prob, x0, linear=KrylovLU())
    assert sd.converged and sk.converged
    assert sd.max_residual <= NEWTON_TOL and sk.max_residual <= NEWTON_TOL
    assert np.max(np.abs(xk - xd)) < 1e-9
    assert sd.factorizations == sd.iterations >= 3
    assert sk.factorizations < sd.factorizations and sk.krylov_iterations > 0
    # a stale LU handed in: Krylov needs no LU at all
    lu = lu_factor(SteadyProblem(params, 1.2, p.xi, p.pin_index, p.y_pin, H=p.H)
                   .residual_and_jacobian(x0)[1])
    xs, ss = newton(prob, x0, linear=KrylovLU(), lu=lu)
    assert ss.converged and ss.factorizations == 0
    assert np.max(np.abs(xs - xd)) < 1e-9


def test_grid_check_with_krylov_steps_gives_the_same_check(params):
    """The 2N − 1 re-solve of a grid check with KrylovLU("single") against DirectLU("single"):
    the same fine pulse and the same (Δβ, ΔL/L), with fewer LUs."""
    sol = as_both(params, solve_pulse(params, 1.2, n_points=400))
    a, db0, dl0 = grid_change(params, sol, 400, nested=True, stages=4, max_iter=15,
                              linear=DirectLU("single"))
    b, db1, dl1 = grid_change(params, sol, 400, nested=True, stages=4, max_iter=15,
                              linear=KrylovLU("single"))
    assert a.stats.converged and b.stats.converged
    assert np.max(np.abs(a.x - b.x)) < 1e-9
    assert abs(dl0) > 1e-6
    assert (db1, dl1) == pytest.approx((db0, dl0), rel=1e-6)
    assert b.stats.factorizations < a.stats.factorizations


def test_a_march_with_krylov_correctors_gives_the_same_pulses(params, pulse12):
    """Five secant steps of ds = 0.001 from the 1.2 pulse on a stretched grid, the corrector's
    steps by an LU each or by GMRES on the LU in hand: the same pulses to 1e-9, fewer LUs."""
    def march(linear):
        m = Continuation(params, (pulse12.xi, pulse12.x[:-1], pulse12.beta, 1.2), Strategy(
            SecantPredictor(), NewtonCorrector(max_iter=20, chord=True, linear=linear),
            FreeSteps(ds=0.001, ds_max=0.001, ds_min=0.00025),
            StretchGrid(relay=0, recentre=0.0)))
        xs, lus = [], 0
        for _ in range(5):
            m.ds = 0.001
            assert m.step() is None
            xs.append(m.sol.x.copy())
            lus += m.sol.stats.factorizations
        return np.array(xs), lus
    xd, lus_d = march(DirectLU())
    xk, lus_k = march(KrylovLU())
    assert np.max(np.abs(xk - xd)) < 1e-9
    assert lus_k < lus_d


def test_a_linear_solve_is_a_value_refused_when_invalid():
    assert str(KrylovLU("single")) and KrylovLU() != DirectLU()
    for bad in (dict(max_iter=0), dict(rtol=0.0), dict(rtol=1.5)):
        with pytest.raises(ValueError, match="krylov"):
            KrylovLU(**bad)
    with pytest.raises(ValueError, match="precision"):
        DirectLU("quad")


def test_a_krylov_march_keeps_its_lu_across_a_replace(params, pulse12):
    """A march whose pulse is replaced (as by a grid check or a recentring) keeps, with a Krylov
    corrector, the last LU as its preconditioner: the next step factors nothing and lands on the
    pulse of the march that was not interrupted; with an LU per step it factors again."""
    def march(linear, replace):
        m = Continuation(params, (pulse12.xi, pulse12.x[:-1], pulse12.beta, 1.2), Strategy(
            SecantPredictor(), NewtonCorrector(max_iter=20, linear=linear),
            FreeSteps(ds=0.001, ds_max=0.001, ds_min=0.00025),
            StretchGrid(relay=0, recentre=0.0)))
        for k in range(3):
            if replace and k == 2:
                m.replace(m.sol)
            m.ds = 0.001
            assert m.step() is None
        return m
    plain, kept = march(KrylovLU(), False), march(KrylovLU(), True)
    assert kept.sol.stats.factorizations == 0
    assert np.max(np.abs(kept.sol.x - plain.sol.x)) < 1e-8
    assert march(DirectLU(), True).sol.stats.factorizations > 0


@pytest.mark.slow
def test_a_failed_checks_region_solves_share_one_tangent(params, monkeypatch):
    """The grid check's normal line needs the pulse's family tangent (a dense solve at N): the
    region re-solves of ``locate_error`` and the check itself on one pulse solve for it once; a
    pulse with other unknowns solves again."""
    from slippulse.steady.continuation import gridcheck
    sol = as_both(params, solve_pulse(params, 1.2, n_points=300))
    calls = []
    real = gridcheck.family_tangent

    def counted(*a):
        calls.append(1)
        return real(*a)

    monkeypatch.setattr(gridcheck, "family_tangent", counted)
    shares = gridcheck.locate_error(params, sol)
    _, db, dl = grid_change(params, sol, 300, nested=True, stages=4, max_iter=15)
    assert len(shares) == 4 and np.isfinite(db) and len(calls) == 1
    other = as_both(params, solve_pulse(params, 1.19, n_points=300))
    grid_change(params, other, 300, nested=True, stages=4, max_iter=15)
    assert len(calls) == 2
