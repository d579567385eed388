"""Continuation of the family on a short coarse range, and resume after interruption."""
import math

import numpy as np
import pytest

from slippulse.steady.continuation import GRID_TOLERANCE, FamilyRun, run_family
from slippulse.core.h5io import list_pulses, read_pulse
from slippulse.core.params import ParameterError


def test_short_family_and_resume(params, tmp_path):
    out = str(tmp_path / "fam.h5")
    rep = run_family(params, out, FamilyRun(start=1.2, stop=1.19, step=0.005, n_points=500))
    assert rep.written == ["td1.2000", "td1.1950", "td1.1900"] and not rep.stopped_early
    pulses = [read_pulse(out, lab)[0] for lab in list_pulses(out)]
    assert all(p.converged and p.max_residual <= 1e-13 for p in pulses)
    beta = [p.beta for p in pulses]
    assert np.all(np.diff(beta) > 0)                # pulses speed up as τ_d decreases
    # "interrupted" run: extend the range; the existing pulses are not recomputed
    before = {lab: read_pulse(out, lab)[0].wall_time for lab in list_pulses(out)}
    rep2 = run_family(params, out, FamilyRun(start=1.2, stop=1.18, step=0.005, n_points=500))
    assert rep2.resumed_from == "td1.1900"
    assert rep2.written == ["td1.1850", "td1.1800"]
    after = {lab: read_pulse(out, lab)[0].wall_time for lab in before}
    assert after == before
    # continuation and a direct solve from the neighbour agree on the same grid size
    assert read_pulse(out, "td1.1800")[0].beta == pytest.approx(0.012002, rel=1e-3)


def test_family_refuses_bad_ranges(params, tmp_path):
    with pytest.raises(ParameterError, match="to="):
        run_family(params, str(tmp_path / "f.h5"), FamilyRun(start=1.1, stop=1.2))
    with pytest.raises(ParameterError, match="tau_d/tau_min"):
        run_family(params, str(tmp_path / "f.h5"), FamilyRun(start=1.2, stop=0.99))
    with pytest.raises(ParameterError, match="step"):
        run_family(params, str(tmp_path / "f.h5"), FamilyRun(start=1.2, stop=1.1, step=-0.01))


def test_beta_mode_inverts_tau_d_mode(params):
    """Fixing β at the speed found at τ_d = 1.2 τ_min and solving for τ_d gives back 1.2."""
    from slippulse.steady.continuation import solve_at_beta
    from slippulse.steady.solver import solve_pulse
    a = solve_pulse(params, 1.2, n_points=600)
    assert a.stats.converged
    b = solve_at_beta(params, (a.xi, a.x[:-1]), 1.199, a.beta, 600)
    assert b.stats.converged
    assert float(b.x[-1]) == pytest.approx(1.2, abs=2e-6)
    pb = b.to_pulse()
    assert pb.max_residual <= 1e-13 and pb.beta == a.beta


def test_interrupted_family_leaves_valid_file_and_resumes(params, tmp_path):
    """Ctrl-C in the middle of a family: the file holds the pulses finished before, and a rerun
    continues from the last of them."""
    out = str(tmp_path / "fam.h5")
    seen = []

    def interrupt_after_two(ratio, pulse, msg):
        seen.append(ratio)
        if len(seen) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_family(params, out, FamilyRun(start=1.2, stop=1.185, step=0.005, n_points=500),
                                          progress=interrupt_after_two)
    # the pulse whose progress call was interrupted had not been written yet
    assert list_pulses(out) == ["td1.2000"]
    rep = run_family(params, out, FamilyRun(start=1.2, stop=1.185, step=0.005, n_points=500))
    assert rep.resumed_from == "td1.2000"
    assert list_pulses(out) == ["td1.2000", "td1.1950", "td1.1900", "td1.1850"]
    assert all(read_pulse(out, lab)[0].converged for lab in list_pulses(out))


# ------------------------------------------------------------------ what a family run reports
class _Injector:
    """Wraps Newton: solves whose problem matches `fail` return at once as not converged.
    Counts the injected failures independently of the code under test."""

    def __init__(self, real, fail):
        self.real, self.fail, self.injected = real, fail, 0

    def __call__(self, problem, x0, **kw):
        from slippulse.steady.newton import SolveStats
        if self.fail(problem):
            self.injected += 1
            return np.array(x0, float), SolveStats(False, "injected failure", 0, np.inf)
        return self.real(problem, x0, **kw)


def _inject(monkeypatch, fail):
    import slippulse.steady.continuation as cont
    import slippulse.steady.newton as nw
    inj = _Injector(nw.newton, fail)
    monkeypatch.setitem(nw.SOLVERS, "newton", inj)
    for mod in (cont.natural, cont.gridcheck, cont.homotopy):
        monkeypatch.setattr(mod, "newton", inj)
    return inj


def _deep_failures(problem):
    """τ_d steps below 1.1935 fail, and every β-step (τ_d free): the run must stop at 1.195."""
    if not hasattr(problem, "free"):           # the grid checks' re-solves: never
        return False
    return problem.free == "tau_d" or problem.tau_d_ratio < 1.1935


def _failing_strategy():
    """The product's strategy with a corrector that fails at once (counted in FAILED), free steps
    from 0.1 down to 0.02 and no relay: the deep march fails after three attempts."""
    from slippulse.steady.continuation import (AUTO, FreeSteps, NewtonCorrector, StretchGrid)
    from slippulse.steady.newton import SolveStats

    class Failing(NewtonCorrector):
        def solve(self, problem, x0, lu=None, creep=None):
            FAILED[0] += 1
            return np.array(x0, float), SolveStats(False, "injected failure", 0, np.inf)

    return AUTO.replace(corrector=Failing(), steps=FreeSteps(ds=0.1, ds_min=0.02),
                        grid=StretchGrid(relay=0, recentre=0.0))


FAILED = [0]


def test_family_counts_every_failed_attempt_and_says_why_it_stopped(params, tmp_path, monkeypatch):
    """τ_d steps below 1.1935 and every β-step fail: the family goes on from 1.195 by the deep
    march, whose correctors fail too (ds 0.1, 0.05, 0.025, then below ds_min): every failure is
    counted and the run says where and why it stopped."""
    inj = _inject(monkeypatch, _deep_failures)
    FAILED[0] = 0
    calls = []
    rep = run_family(params, str(tmp_path / "f.h5"), FamilyRun(start=1.2, stop=1.185, step=0.005,
                                                               n_points=500, deep_points=500,
                                                               n_max=4000,
                                                               strategy=_failing_strategy()),
                                                               progress=lambda r, p,
                                                               m: calls.append(p is None))
    # 1.19 fails, 1.1925 (halved) fails, then two β-steps (shrink 0.92, 0.96) fail: four; the
    # deep march's three attempts (ds 0.1, 0.05, 0.025; a predictor out of range fails before
    # its corrector)
    assert inj.injected == 4 and 1 <= FAILED[0] <= 3
    assert len(rep.failures) == inj.injected + 3 == sum(calls)
    assert rep.attempts == len(calls) == 2 + 4 + 1 + 3      # + the deep start's re-solve
    assert rep.written == ["td1.2000", "td1.1950"]
    assert rep.stopped_early and rep.reached == pytest.approx(1.195)
    assert rep.reached_beta == pytest.approx(read_pulse(str(tmp_path / "f.h5"), "td1.1950")[0].beta)
    assert "arclength steps stopped converging" in rep.stop_reason and "--ds-min" in rep.hint
    assert any("beta-step" in m for _, m in rep.failures)


def test_family_command_final_line_names_where_why_and_how_to_go_further(tmp_path, monkeypatch,
                                                                         capsys):
    import slippulse.steady.continuation as cont
    import slippulse.steady.continuation.family as fam
    from slippulse import cli
    inj = _inject(monkeypatch, _deep_failures)
    FAILED[0] = 0
    monkeypatch.setattr(cont, "AUTO", _failing_strategy())
    monkeypatch.setattr(fam, "DEEP_POINTS", 500)
    out = str(tmp_path / "f.h5")
    rc = cli.main(["steady", "family", "--from", "1.2", "--to", "1.185", "--step", "0.005",
                   "--points", "500", "--out", out, "-q", "--ds-min", "0.02"])
    assert rc == 1
    text = capsys.readouterr().out
    assert f"{inj.injected + 3} failed" in text and inj.injected == 4
    stop = [ln for ln in text.splitlines() if ln.startswith("STOPPED EARLY")]
    assert len(stop) == 1
    assert "tau_d/tau_min=1.19500" in stop[0] and "1.1850 not reached" in stop[0]
    beta = read_pulse(out, "td1.1950")[0].beta
    assert f"beta={beta:.6f}" in stop[0]
    assert "arclength steps stopped converging" in stop[0] and "--ds-min" in stop[0]


def test_progress_moves_on_beta_steps_and_counts_failures():
    from types import SimpleNamespace
    from slippulse.cli.steady import FamilyProgress
    prog = FamilyProgress(1.2, 1.0, 0.005)
    assert prog.total == 41
    prog(1.2, SimpleNamespace(tau_d_ratio=1.2, beta=0.007, L=1.0), "ok")
    assert prog.position == 1.0
    # a β-step pulse between targets moves the bar by the fraction of a step it covered
    prog(1.01, SimpleNamespace(tau_d_ratio=1.0123, beta=0.99, L=150.0), "beta-step")
    assert prog.position == pytest.approx(1 + (1.2 - 1.0123) / 0.005)
    prog(1.0115, None, "failed")
    prog(1.013, SimpleNamespace(tau_d_ratio=1.013, beta=0.98, L=100.0), "fold: back up")
    assert prog.position == pytest.approx(1 + (1.2 - 1.0123) / 0.005)     # never moves back
    assert prog.failed == 1


# ------------------------------------------------------------------ pseudo-arclength
def test_arclength_row_and_tangent(params):
    """The appended arclength row is the derivative of the arclength condition (central
    differences), and the tangent lies in the null space of the steady Jacobian."""
    from slippulse.steady.continuation import ArclengthProblem, family_tangent
    from slippulse.steady.solver import default_guess
    from slippulse.steady.equations import SteadyProblem
    xi, y, beta = default_guess(params, 1.2, 120)
    k = int(np.argmin(np.abs(xi)))
    base = SteadyProblem(params, 1.2, xi, k, float(y[k]), free="both")
    x = np.concatenate([y, [beta, 1.2]])
    arc = ArclengthProblem(base, np.log(1 - 0.9 * beta), 1.19, -0.6, -0.8, 0.05, 0.01)
    r, J = arc.residual_and_jacobian(x)
    assert J.shape == (x.size, x.size) and np.allclose(r, arc.residual(x), rtol=0, atol=1e-14)
    for j in (x.size - 2, x.size - 1):
        h = 1e-7
        e = np.zeros_like(x)
        e[j] = h
        fd = (arc.residual(x + e)[-1] - arc.residual(x - e)[-1]) / (2 * h)
        assert J[-1, j] == pytest.approx(fd, rel=1e-6)
    n = family_tangent(base, x, (1.0, 0.0, 0.05))
    _, Jb = base.residual_and_jacobian(x)
    assert np.max(np.abs(Jb @ n)) < 1e-9 * np.abs(Jb).max() * np.abs(n).max()
    assert np.hypot(-n[-2] / (1 - beta), n[-1] / 0.05) == pytest.approx(1.0, rel=1e-12)
    assert n[-2] > 0                                     # oriented toward larger β


def _plain(ds, stretch=False):
    """Fixed arclength steps ``ds`` on an adapted (or stretched) grid, 20 Newton iterations."""
    from slippulse.steady.continuation import (AdaptGrid, FreeSteps, NewtonCorrector, Strategy,
                                               StretchGrid, TangentPredictor)
    return Strategy(TangentPredictor(), NewtonCorrector(max_iter=20),
                    FreeSteps(ds=ds, ds_max=ds, ds_min=ds / 4),
                    StretchGrid(relay=0, recentre=0.0) if stretch else AdaptGrid())


def test_arclength_steps_stay_on_the_family(params):
    """Two pseudo-arclength steps from the 1.2 pulse: each a converged pulse (β and τ_d both
    unknown) that a fixed-τ_d solve at its τ_d reproduces, moving toward τ_min and larger β."""
    from slippulse.steady.continuation import Continuation
    from slippulse.steady.solver import solve_pulse
    a = solve_pulse(params, 1.2, n_points=500)
    m = Continuation(params, (a.xi, a.x[:-1], a.beta, 1.2), _plain(0.004))
    steps = []
    for _ in range(2):
        assert m.step() is None
        steps.append(m.sol)
    qs = [float(s.x[-1]) for s in steps]
    bs = [s.beta for s in steps]
    assert 1.2 > qs[0] > qs[1] and a.beta < bs[0] < bs[1]
    for s in steps:
        pu = s.to_pulse()
        assert pu.converged and pu.max_residual <= 1e-13 and pu.extra["n_humps"] == 1
        # the same grid, τ_d fixed at the arclength value: β comes back
        b = solve_pulse(params, float(s.x[-1]), n_points=500, guess=(s.xi, s.x[:-2], s.beta * 1.01),
                        passes=0, adapt_guess=False)
        assert b.stats.converged and b.beta == pytest.approx(s.beta, rel=1e-8)


class _ToyFold:
    """x = (y, β, q): equations y − β = 0, q − 1 − (β − 0.5)² = 0 (one fewer than unknowns, like
    SteadyProblem(free='both')). q(β) has a fold (minimum) at β = 0.5, q = 1."""

    def valid(self, x):
        return 0.0 < x[-2] < 1.0

    def residual(self, x):
        return np.array([x[0] - x[1], x[2] - 1.0 - (x[1] - 0.5) ** 2])

    def residual_and_jacobian(self, x, extra_rows=0):
        J = np.array([[1.0, -1.0, 0.0], [0.0, -2.0 * (x[1] - 0.5), 1.0]] + [[0.0] * 3] * extra_rows)
        return self.residual(x), J


def test_arclength_follows_a_fold():
    """The arclength pieces (tangent, closure row, Newton) pass a fold in q: q first decreases,
    then increases, while β keeps increasing; fixed-q stepping could not pass it."""
    from slippulse.steady.continuation import ArclengthProblem, family_tangent
    from slippulse.steady.newton import newton
    toy = _ToyFold()
    x = np.array([0.2, 0.2, 1.09])
    kappa, orient = 0.3, (1.0, 0.0, 0.3)
    qs, bs, tq = [], [], []
    for _ in range(40):
        n = family_tangent(toy, x, orient)
        orient = (n[-2], n[-1], kappa)
        t_a, t_Q = -n[-2] / (1 - x[-2]), n[-1] / kappa
        arc = ArclengthProblem(toy, np.log(1 - x[-2]), x[-1], t_a, t_Q, kappa, 0.05)
        x, st = newton(arc, x + 0.05 * n, tol=1e-13, max_iter=20)
        assert st.converged
        qs.append(x[-1]), bs.append(x[-2]), tq.append(t_Q)
        if x[-2] > 0.8:
            break
    assert np.all(np.diff(bs) > 0) and bs[-1] > 0.8
    k = int(np.argmin(qs))
    assert 0 < k < len(qs) - 1 and abs(bs[k] - 0.5) < 0.05 and qs[k] == pytest.approx(1.0, abs=3e-3)
    assert tq[0] < 0 < tq[-1]
    assert max(abs(np.asarray(qs) - 1 - (np.asarray(bs) - 0.5) ** 2)) < 1e-12


def test_grid_check_equals_fixed_tau_d_difference(params):
    """check_grid_2n solves the 2N pulse on the normal to the tangent and converts the change
    to fixed τ_d along the tangent; a fixed-τ_d solve on the same 2N grid gives the same Δβ, ΔL/L."""
    from slippulse.steady.continuation import as_both, check_grid_2n, solve_at_beta
    from slippulse.steady.solver import solve_pulse
    # N = 300: with the order-4 state integration N = 400 and 800 agree in τ_d to 3e-8 only
    a = solve_pulse(params, 1.19, n_points=300)
    coarse = solve_at_beta(params, (a.xi, a.x[:-1]), 1.19, a.beta, 300)     # τ_d ≈ 1.19 at this β
    assert coarse.stats.converged
    sol = as_both(params, coarse)
    fine, db, dl = check_grid_2n(params, sol, 300)
    assert fine.stats.converged and fine.problem.n == 600
    q = float(sol.x[-1])
    assert abs(float(fine.x[-1]) - q) > 1e-7              # the grids disagree measurably
    direct = solve_pulse(params, q, n_points=600, guess=(fine.xi, fine.x[:-2], sol.beta),
                         passes=0, adapt_guess=False)
    assert direct.stats.converged
    p0, p2 = sol.to_pulse(), direct.to_pulse()
    assert db == pytest.approx(abs(p2.beta - p0.beta), rel=1e-3)
    assert dl == pytest.approx(abs(p2.L - p0.L) / p0.L, rel=1e-2)


@pytest.mark.parametrize("stages", [0, 4])
def test_grid_check_reusing_the_lu_gives_the_same_check_with_fewer_factorisations(params, stages):
    """The nested check's re-solve with reuse=True (chord iterations on each full Newton step's
    LU) converges to the solution of plain Newton, with fewer LUs; Δβ and ΔL/L are the same.
    stages=4 is the path of the family's check (:func:`check_pulse`, through solve_robust)."""
    from slippulse.steady.continuation.gridcheck import as_both, grid_change
    from slippulse.steady.solver import solve_pulse
    sol = as_both(params, solve_pulse(params, 1.2, n_points=400))
    plain, db0, dl0 = grid_change(params, sol, 400, nested=True, reuse=False, stages=stages)
    fast, db1, dl1 = grid_change(params, sol, 400, nested=True, reuse=True, stages=stages)
    assert plain.stats.converged and fast.stats.converged
    assert plain.stats.chord_iterations == 0 and fast.stats.chord_iterations > 0
    assert fast.stats.iterations < plain.stats.iterations
    assert np.max(np.abs(fast.x - plain.x)) < 1e-9
    assert abs(db1 - db0) < 1e-6 * abs(db0) and abs(dl1 - dl0) < 1e-6 * abs(dl0)


def test_grid_check_with_a_single_precision_lu_gives_the_double_check(params):
    """NestedCheck(DirectLU("single")): the 2N − 1 re-solve factors the Jacobian in float32, keeps the
    residual and the iterates in double, and converges to the same tolerance: the same fine
    pulse and the same Δβ, ΔL/L as the double LU, in as many LUs; the check's attributes name
    the method; a precision that does not exist is refused."""
    from slippulse.steady.continuation.gridcheck import as_both, check_pulse, grid_change
    from slippulse.steady.continuation.strategy import NestedCheck
    from slippulse.steady.newton import DirectLU, newton
    from slippulse.steady.solver import solve_pulse
    sol = as_both(params, solve_pulse(params, 1.2, n_points=400))
    dbl, db0, dl0 = grid_change(params, sol, 400, nested=True, stages=4, max_iter=15,
                                linear="double")
    sgl, db1, dl1 = grid_change(params, sol, 400, nested=True, stages=4, max_iter=15,
                                linear="single")
    assert dbl.stats.converged and sgl.stats.converged
    assert sgl.stats.iterations == dbl.stats.iterations
    assert np.max(np.abs(sgl.x - dbl.x)) < 1e-9
    assert abs(db1 - db0) < 1e-6 * abs(db0) and abs(dl1 - dl0) < 1e-6 * abs(dl0)
    assert abs(dl0) > 1e-6                                   # a change the grids make
    res = check_pulse(params, sol, method=NestedCheck(DirectLU("single")), body_levels=0,
                      n_max=2 * 400 - 1)                  # one level: the re-solve above
    assert res.attrs(GRID_TOLERANCE)["grid_check_method"] == \
        "nested(linear=lu(precision=single))"
    assert (res.dbeta, res.dL_rel) == pytest.approx((abs(db1), abs(dl1)), rel=1e-12)
    with pytest.raises(ValueError, match="precision"):
        newton(sol.problem, sol.x, linear="half")


def test_tangent_step_converges_on_the_tangents_lu_to_the_direct_solution(params):
    """A τ_d step of the family from 1.2 to 1.195 τ_min on the 1.2 pulse's grid: the tangent
    predictor lands close enough for the corrector to converge on the tangent's LU alone (no LU
    of its own), and the result is the solution of a fresh Newton solve on the same grid."""
    from slippulse.steady.continuation import PulseOnGrid, tangent_step
    from slippulse.steady.equations import SteadyProblem
    from slippulse.steady.newton import newton
    from slippulse.steady.solver import solve_pulse
    a = solve_pulse(params, 1.2, n_points=500)
    sol, base = tangent_step(params, PulseOnGrid.of(a, a.to_pulse().L), 1.195, "tau_d", 500)
    assert sol.stats.converged and sol.stats.factorizations == 0
    assert sol.stats.krylov_iterations > 0
    assert sol.xi is a.xi and base.q == 1.195 and base.H is a.problem.H
    # the same equations solved by plain Newton from the 1.2 pulse
    prob = SteadyProblem(params, 1.195, a.xi, a.problem.pin_index, a.problem.y_pin, H=a.problem.H)
    x, st = newton(prob, a.x)
    assert st.converged and st.iterations >= 2
    assert abs(sol.beta / x[-1] - 1) < 1e-10 and np.max(np.abs(sol.x[:-1] - x[:-1])) < 1e-8


def test_a_natural_step_on_the_fold_tests_lu_predicts_as_on_its_own(params):
    """The fold test's LU of A = ∂(Δ, pin)/∂(ln v, β) (column-scaled by β), handed to the next
    natural step, replaces that step's own factorisation: the τ_d and β steps predict the same
    tangent (the same first residual) and converge to the same pulse, with no LU formed."""
    from slippulse.steady.bifurcation import FamilyMonitor
    from slippulse.steady.continuation import PulseOnGrid, tangent_step
    from slippulse.steady.continuation.strategy import BETA_STEPS, NATURAL
    from slippulse.steady.solver import solve_pulse
    a = solve_pulse(params, 1.2, n_points=500)
    FamilyMonitor(params)(a, a.to_pulse())
    assert a.fold_lu is not None
    lu, piv = a.fold_lu
    P = np.eye(piv.size)
    for i, j in enumerate(piv):          # LAPACK's row interchanges, applied in order
        P[[i, j]] = P[[j, i]]
    from slippulse.steady.equations import SteadyProblem
    both = SteadyProblem(params, 1.2, a.xi, a.problem.pin_index, a.problem.y_pin, free="both",
                         H=a.problem.H)
    _, J = both.residual_and_jacobian(np.concatenate([a.x, [1.2]]))
    A = J[:, :-1]
    Lm, Um = np.tril(lu, -1) + np.eye(piv.size), np.triu(lu)
    assert np.max(np.abs(P @ A - Lm @ Um)) <= 1e-10 * np.max(np.abs(A))   # the LU of A itself
    L = a.to_pulse().L
    for fixed, value, corrector in (("tau_d", 1.195, NATURAL.corrector),
                                    ("beta", 1.02 * a.beta, BETA_STEPS.corrector)):
        base = PulseOnGrid.of(a, L)
        own = PulseOnGrid.of(a, L)
        own.lu_a = None
        s1, _ = tangent_step(params, base, value, fixed, 500, corrector=corrector)
        s0, _ = tangent_step(params, own, value, fixed, 500, corrector=corrector)
        assert s1.stats.converged and s0.stats.converged
        assert s1.stats.factorizations == 0
        assert s1.stats.history[0] == pytest.approx(s0.stats.history[0], rel=1e-6)
        assert np.max(np.abs(s1.x - s0.x)) <= 1e-9


def test_stretch_grid_lengthens_the_body_and_keeps_both_edges():
    """The nodes within a of the front stay, the healing-front zone and all behind it move by
    exactly −shift, the body between stretches monotonically; shift = 0 is the identity."""
    from slippulse.steady.continuation import stretch_grid
    xi = np.sort(np.concatenate([np.linspace(-300, 50, 3000), np.linspace(-0.5, 0.5, 500)]))
    x0, a, x_back, w = 0.0, 1.0, -100.0, 5.0
    for shift in (-8.0, 0.0, 12.0):
        xn = stretch_grid(xi, x0, shift, a, x_back, w)
        assert np.all(np.diff(xn) > 0)
        u = x0 - xi
        np.testing.assert_array_equal(xn[u <= a], xi[u <= a])
        behind = u >= (x0 - x_back) - w
        np.testing.assert_allclose(xn[behind], xi[behind] - shift, rtol=0, atol=1e-12)
        body = (u > 2 * a) & (u < (x0 - x_back) - 2 * w)
        h, hn = np.diff(xi)[body[1:]], np.diff(xn)[body[1:]]
        if shift:
            assert np.all(np.sign(hn - h) == np.sign(shift))


class _Cubic:
    """x = (y, z): y + 0.5 y³ − 3 = 0 (root y = 1.5700...) and z − 1 = 0."""

    def valid(self, x):
        return True

    def residual(self, x):
        return np.array([x[0] + 0.5 * x[0] ** 3 - 3.0, x[1] - 1.0])

    def residual_and_jacobian(self, x):
        return self.residual(x), np.array([[1.0 + 1.5 * x[0] ** 2, 0.0], [0.0, 1.0]])


def test_solve_robust_falls_back_on_the_residual_homotopy(monkeypatch):
    """Two Newton iterations from y = 0 cannot reach 1e-13 on the cubic; the homotopy
    F(x) = s F(x0), s = 1 − k/8, reaches the root, and the iterations of all stages are counted.
    With four iterations per stage, two stages are too long: each failed step is halved and
    made again from the last converged stage (``HALVINGS``); with no halving it fails and says
    at which stage."""
    from slippulse.steady.continuation import homotopy, solve_robust
    x, st = solve_robust(_Cubic(), np.array([0.0, 0.0]), stages=8, max_iter=2)
    assert st.converged and abs(x[0] + 0.5 * x[0] ** 3 - 3.0) <= 1e-13 and x[1] == 1.0
    assert st.iterations > 2
    x, st = solve_robust(_Cubic(), np.array([0.0, 0.0]), stages=2, max_iter=1)
    assert st.converged and abs(x[0] + 0.5 * x[0] ** 3 - 3.0) <= 1e-13
    monkeypatch.setattr(homotopy, "HALVINGS", 0)
    x, st = solve_robust(_Cubic(), np.array([0.0, 0.0]), stages=2, max_iter=1)
    assert not st.converged and "homotopy stage" in st.message


class _Banded:
    """x − 2 = 0 with x in (0.2, 1.8) invalid: plain Newton from 0 jumps the band in one step;
    the homotopy's first stage, x = 0.25, lies inside it and cannot be reached."""

    def valid(self, x):
        return not 0.2 < x[0] < 1.8

    def residual(self, x):                  # (y, β, q)-shaped: two more unknowns, at 1
        return np.array([x[0] - 2.0, x[1] - 1.0, x[2] - 1.0])

    def residual_and_jacobian(self, x):
        return self.residual(x), np.eye(3)


def test_a_homotopy_tried_first_gives_way_to_plain_newton():
    """``solve_robust(plain=False)`` (the homotopy first, as the deep checks do after one crept):
    where the homotopy fails, plain Newton runs after it and its result is returned; where both
    fail the message names both."""
    from slippulse.steady.continuation import solve_robust
    x, st = solve_robust(_Banded(), np.array([0.0, 1.0, 1.0]), stages=8, max_iter=3, plain=False)
    assert st.converged and x[0] == 2.0 and st.homotopy
    x, st = solve_robust(_Trapped(), np.array([0.0, 1.0, 1.0]), stages=2, max_iter=1,
                         plain=False)
    assert not st.converged
    assert "homotopy stage" in st.message and "then plain Newton" in st.message


class _Trapped(_Banded):
    """_Banded with a Jacobian twice too large: every Newton step lands in the band or short of
    it, so plain Newton fails too; the homotopy's stages lie in the band however halved."""

    def residual_and_jacobian(self, x):
        return self.residual(x), 2.0 * np.eye(3)


class _Slow(_Cubic):
    """The cubic with a Jacobian 10 times too large: every full Newton step is a tenth of the
    right one, so max|r| falls by ≈ 10 % per iteration (a creeping iteration)."""

    def residual_and_jacobian(self, x):
        r, J = super().residual_and_jacobian(x)
        return r, 10.0 * J


def test_newton_stops_creeping_iterations_when_asked():
    """creep=3: Newton gives up once max|r| has not halved over 3 iterations (here at the 3rd:
    0.9³ > 0.5 is not, 0.9⁷ is; the first halving takes 7), says so, and counts them; creep=0
    goes on to max_iter. A converging iteration is not stopped."""
    from slippulse.steady.newton import newton
    x0 = np.array([1.0, 1.0])
    _, st0 = newton(_Slow(), x0, max_iter=12)
    _, st3 = newton(_Slow(), x0, max_iter=12, creep=3)
    assert not st0.converged and st0.iterations == 12
    assert not st3.converged and "creeping" in st3.message and st3.iterations == 3
    ratios = np.array(st0.history[3:]) / np.array(st0.history[:-3])
    assert np.all(ratios > 0.5)                      # creeping all along
    x, st = newton(_Cubic(), np.array([0.0, 0.0]), max_iter=30, creep=3)
    assert st.converged and abs(x[0] + 0.5 * x[0] ** 3 - 3.0) <= 1e-13


def test_natural_newton_creeps_only_when_neither_residual_nor_correction_halves():
    """line_search="natural" with creep: max|r| may rise on the way in (its test makes the Newton
    corrections fall, not max|r|), so the iteration creeps only when neither max|r| nor ‖δ‖₂
    has halved over `creep` iterations. On the steep 3-equation system max|r| goes 3.8e3 →
    7.9e3 → 3.4e3 (not halved over 2) while ‖δ‖₂ falls 340 → 0.62: natural converges with
    creep=2, where a max|r|-only rule would have stopped it at the 2nd iteration (and does stop
    the residual line search there). On the cubic with a Jacobian 10 times too large both fall by
    only ≈ 10 % per iteration: it creeps, and says so."""
    from slippulse.steady.newton import newton
    from test_spectrum_cost import _Steep
    x0 = np.array([-1.863, -1.276, -0.424])
    x, st = newton(_Steep((1.0, 1e4, 1.0)), x0, tol=1e-7, line_search="natural", creep=2)
    assert st.converged and st.iterations == 7
    assert st.history[2] > 0.5 * st.history[0]              # max|r| alone: creeping at it 2
    assert st.corrections[2] <= 0.5 * st.corrections[0]
    _, st_r = newton(_Steep((1.0, 1e4, 1.0)), x0, tol=1e-7, line_search="residual", creep=2)
    assert not st_r.converged and "creeping" in st_r.message and st_r.iterations == 2
    # r = x − 1 with a Jacobian 3.7 times too large: each full step passes the natural test
    # (‖δ̄‖/‖δ‖ = 1 − 1/3.7 = 0.73 ≤ 0.75) and both measures fall by 0.73 per iteration,
    # 0.73² > 1/2: creeping at the 2nd
    _, st_s = newton(_Lazy(), np.array([3.0, 3.0]), max_iter=12, line_search="natural", creep=2)
    assert not st_s.converged and "creeping" in st_s.message and st_s.iterations == 2
    assert "Newton correction" in st_s.message
    x, st_c = newton(_Lazy(), np.array([3.0, 3.0]), max_iter=120, line_search="natural")
    c = np.array(st_c.corrections[:11])
    assert st_c.converged and np.allclose(c[1:] / c[:-1], 1 - 1 / 3.7)


class _Lazy(_Cubic):
    """r = x − 1 with a Jacobian 3.7 times too large (a linear, slowly converging iteration)."""

    def residual(self, x):
        return x - 1.0

    def residual_and_jacobian(self, x):
        return x - 1.0, 3.7 * np.eye(2)


class _Floor(_Cubic):
    """The cubic with |r₀| ≥ `floor` everywhere (a floor like round-off's, of either sign across
    the root): no Newton step lowers ‖r‖₂ below it."""

    def __init__(self, floor):
        self.floor = floor

    def residual(self, x):
        r = super().residual(x)
        r[0] += math.copysign(self.floor, r[0])
        return r

    def residual_and_jacobian(self, x):
        return self.residual(x), super().residual_and_jacobian(x)[1]


def test_newton_accepts_the_round_off_floor_within_ROUNDOFF_of_tol():
    """A line search that finds no lower ‖r‖₂ ends Newton as converged when max|r| is within
    ROUNDOFF of tol (measured on the deep march: 1.11e-13 against 1e-13 ended it), and as failed
    when the floor is farther above tol."""
    from slippulse.steady.newton import ROUNDOFF, newton
    x, st = newton(_Floor(2e-13), np.array([1.0, 0.0]), tol=1e-13, max_iter=40)
    assert st.converged and "round-off" in st.message and st.max_residual > 1e-13
    assert abs(x[0] + 0.5 * x[0] ** 3 - 3.0) <= ROUNDOFF * 1e-13
    x, st = newton(_Floor(3e-12), np.array([1.0, 0.0]), tol=1e-13, max_iter=40)
    assert not st.converged and "line search failed" in st.message


def test_solve_robust_starts_with_the_homotopy_when_told():
    """plain=False: no plain Newton solve (its iterations are not spent), the homotopy from the
    start, to the same root, and stats.homotopy says so; a plain solve that converges does not
    set it."""
    from slippulse.steady.continuation import solve_robust
    import slippulse.steady.continuation.homotopy as hm
    calls = []
    real = hm.newton

    def spy(problem, x0, **kw):
        calls.append(type(problem).__name__)
        return real(problem, x0, **kw)

    hm.newton = spy
    try:
        x, st = solve_robust(_Cubic(), np.array([0.0, 0.0]), stages=4, max_iter=30, plain=False)
        assert calls == ["_Shifted"] * 4 and st.converged and st.homotopy
        assert abs(x[0] + 0.5 * x[0] ** 3 - 3.0) <= 1e-13
        calls.clear()
        x, st = solve_robust(_Cubic(), np.array([0.0, 0.0]), stages=4, max_iter=30)
        assert calls == ["_Cubic"] and st.converged and not st.homotopy
    finally:
        hm.newton = real


def test_checks_start_with_the_homotopy_after_one_needed_it(monkeypatch):
    """Checker: after a check whose plain re-solve needed the homotopy, the next
    HOMOTOPY_FIRST checks are asked to start with it (plain=False), then plain Newton again."""
    from types import SimpleNamespace
    from slippulse.steady.continuation import family
    asked = []
    crept = iter([False, True] + [True] * family.HOMOTOPY_FIRST + [False, False])

    def check(params, sol, tol, n_max, log=None, body_levels=0, locate=False, plain=True,
              warm=None, method=None):
        asked.append(plain)
        homotopy = next(crept)
        return SimpleNamespace(passed=False, homotopy=homotopy, message="mock", sol=sol,
                               attrs=lambda tol: {}, warm=None)

    monkeypatch.setattr(family, "check_pulse", check)
    w = family.Checker(None, None, 4000)
    pulse = SimpleNamespace(extra={}, label="td1.0085", tau_d_ratio=1.0085, name="",
                            converged=True)
    sol = SimpleNamespace(to_pulse=lambda: pulse)
    for _ in range(3 + family.HOMOTOPY_FIRST):
        w(sol, "arclength")
    k = family.HOMOTOPY_FIRST
    assert asked == [True, True] + [False] * k + [True]


def test_stretched_march_and_nested_grid_check(params):
    """StretchGrid: the grid is deformed with the pulse every step (same N, the nodes ahead of the
    front kept, the healing front and tail shifted), the steps are converged pulses on the family
    (fixed-τ_d solve on the step's grid returns its β); the nested check (2N − 1 nodes, the
    N-grid's nodes kept) gives small N-vs-2N differences, and its pulse replaces the march's."""
    from slippulse.steady.continuation import Continuation, check_grid_2n
    from slippulse.steady.solver import solve_pulse
    a = solve_pulse(params, 1.2, n_points=500)
    m = Continuation(params, (a.xi, a.x[:-1], a.beta, 1.2), _plain(0.004, stretch=True))
    steps = []
    while len(steps) < 2:
        assert m.step() is None
        sol = m.sol
        steps.append(sol)
        if len(steps) == 1:
            fine, db, dl = check_grid_2n(params, sol, 500, nested=True, stages=4)
            assert fine.stats.converged and fine.problem.n == 999
            assert np.array_equal(fine.xi[::2], sol.xi)
            assert 0 < db < 1e-3 and 0 < dl < 1e-2
            # a cell mask selecting every cell is the full nested check; the body alone is a
            # grid between the two (the N-grid's nodes kept, the pin on its node)
            every = np.ones(sol.xi.size - 1, bool)
            f2, db2, dl2 = check_grid_2n(params, sol, 500, nested=True, stages=4, cells=every)
            assert np.array_equal(f2.x, fine.x) and (db2, dl2) == (db, dl)
            L = sol.to_pulse().L
            mid = 0.5 * (sol.xi[1:] + sol.xi[:-1])
            xf = sol.xi[sol.problem.pin_index]
            body = (mid > xf - 0.9 * L) & (mid <= xf - 0.01 * L)
            f3, _, _ = check_grid_2n(params, sol, 500, nested=True, stages=4, cells=body)
            assert f3.stats.converged and f3.problem.n == 500 + int(body.sum())
            assert np.isin(sol.xi, f3.xi).all() and f3.xi[f3.problem.pin_index] == xf
            m.replace(fine)
    assert steps[0].problem.n == 500 and steps[1].problem.n == 999
    assert steps[0].xi[-1] == a.xi[-1] and steps[0].xi[0] != a.xi[0]
    qs = [float(s.x[-1]) for s in steps]
    assert 1.2 > qs[0] > qs[1]
    s = steps[0]
    b = solve_pulse(params, qs[0], n_points=500, guess=(s.xi, s.x[:-2], s.beta * 1.01),
                    passes=0, adapt_guess=False)
    assert b.stats.converged and b.beta == pytest.approx(s.beta, rel=1e-8)


def test_to_refine_picks_the_fewest_regions_that_leave_the_rest_within_tolerance():
    """The located shares are signed and add up: refine the largest until the rest (which may
    cancel) is within 0.8 of the tolerance; a region whose re-solve failed comes first."""
    from slippulse.steady.continuation.gridcheck import BODY, HEALING, LEADING, _to_refine
    from slippulse.steady.continuation.tolerance import GridTolerance
    tol = GridTolerance(beta=1e-5, L=1e-4)
    # measured at 2.43 km: the leading edge alone; body and healing front cancel to -4.5e-5
    assert _to_refine({LEADING: (-7.8e-8, -1.26e-4), BODY: (-4.6e-8, -8.6e-5),
                       HEALING: (4.1e-8, 4.1e-5)}, tol) == [LEADING]
    assert _to_refine({LEADING: (0.0, -2e-5), BODY: (0.0, -1.6e-4), HEALING: (0.0, 1e-5)},
                      tol) == [BODY]
    assert _to_refine({LEADING: (0.0, -9e-5), BODY: (0.0, -9e-5), HEALING: (0.0, 1e-6)},
                      tol) == [LEADING, BODY] or _to_refine(
        {LEADING: (0.0, -9e-5), BODY: (0.0, -9e-5), HEALING: (0.0, 1e-6)}, tol) == [BODY, LEADING]
    assert _to_refine({LEADING: (0.0, math.inf), BODY: (0.0, -1.6e-4), HEALING: (0.0, 1e-5)},
                      tol)[0] == LEADING
    # β decides as well as L
    assert _to_refine({LEADING: (0.0, 0.0), BODY: (0.0, 0.0), HEALING: (2e-5, 0.0)},
                      tol) == [HEALING]


def test_check_pulse_locates_the_error_before_refining(params):
    """locate=True on a marched pulse with a tolerance it misses: the shares of the four inner
    regions add up to about the full nested check's change, and the refined pulse has exactly
    the chosen regions' midpoints inserted (its old nodes kept)."""
    from slippulse.steady.continuation import Continuation, grid_change
    from slippulse.steady.continuation.gridcheck import (INNER, check_pulse, locate_error,
                                                         regions)
    from slippulse.steady.continuation.tolerance import GridTolerance
    from slippulse.steady.solver import solve_pulse
    a = solve_pulse(params, 1.2, n_points=500)
    m = Continuation(params, (a.xi, a.x[:-1], a.beta, 1.2), _plain(0.004, stretch=True))
    assert m.step() is None
    sol = m.sol
    _, db, dl = grid_change(params, sol, 500, nested=True, stages=4)       # signed
    shares = locate_error(params, sol)
    assert list(shares) == list(INNER)
    sum_b = sum(v[0] for v in shares.values())
    sum_l = sum(v[1] for v in shares.values())
    # additive to first order only: here (N = 500, 4 cells in the leading edge) the located sum
    # of ΔL/L is 1.6 times the full change; at 2.43 km (N = 5325) it was within 7 %
    assert np.sign(sum_l) == np.sign(dl) and 0.5 <= sum_l / dl <= 2.0
    tol = GridTolerance(beta=0.3 * abs(db), L=0.3 * abs(dl))      # the N check fails
    lines = []
    res = check_pulse(params, sol, tol, n_max=4000, body_levels=1, locate=True, log=lines.append)
    assert "dL/L by region" in res.message and any("refining" in s for s in lines)
    steps = res.message.split("; ")
    assert steps[1].startswith("dL/L by region")
    where, added = steps[2].rsplit(" +", 1)
    masks = regions(sol, sol.to_pulse().L)
    chosen = [n for n in INNER if n.split(" (")[0] in where.split("+")]
    assert chosen and int(added) == sum(int(masks[n].sum()) for n in chosen)
    assert steps[3].startswith(f"N={500 + int(added)} vs")
    if res.passed:
        assert res.n == 500 + int(added) and np.isin(sol.xi, res.sol.xi).all()


def test_to_refine_keeps_the_refined_check_within_the_largest_grid():
    """At 4.19 km the rule asked for the healing front and the body, whose cells would have
    made the refined pulse's check larger than --max-points; within a cell budget it keeps the
    largest share alone (refined next, the rest located again at the next level)."""
    from slippulse.steady.continuation.gridcheck import BODY, HEALING, LEADING, _to_refine
    from slippulse.steady.continuation.tolerance import GridTolerance
    tol = GridTolerance(beta=1e-5, L=1e-4)
    shares = {LEADING: (0.0, -5.8e-5), BODY: (0.0, -7.1e-5), HEALING: (0.0, -1.8e-4)}
    cells = {LEADING: 1393, BODY: 3000, HEALING: 650}
    assert _to_refine(shares, tol) == [HEALING, BODY]
    assert _to_refine(shares, tol, cells=cells, budget=10000) == [HEALING, BODY]
    assert _to_refine(shares, tol, cells=cells, budget=2369) == [HEALING]
    assert _to_refine(shares, tol, cells=cells, budget=100) == [HEALING]   # kept: N doubles next


def test_the_monitor_sees_every_written_pulse_and_its_figures_are_stored(params, tmp_path):
    """``run_family(monitor=...)``: called on every checked pulse just before it is written (the
    place for a per-pulse computation along the family); its dict is stored with the pulse."""
    out = str(tmp_path / "fam.h5")
    seen = []

    def monitor(sol, pulse):
        seen.append(pulse.tau_d_ratio)
        return {"test_function": float(sol.beta) ** 2}

    rep = run_family(params, out, FamilyRun(start=1.2, stop=1.19, step=0.005, n_points=500),
                                            monitor=monitor)
    labels = list_pulses(out)
    assert labels == rep.written == ["td1.2000", "td1.1950", "td1.1900"]
    assert seen == [read_pulse(out, lab)[0].tau_d_ratio for lab in labels]
    for lab in labels:
        p, _ = read_pulse(out, lab)
        assert p.extra["test_function"] == pytest.approx(p.beta ** 2, rel=1e-15)


def test_nested_refinement_shows_the_fourth_order_of_the_discretisation(params, tmp_path):
    """``grid_convergence``: two nested levels of the 1.2 τ_min pulse (N = 500 → 999 → 1997)
    change β and L by factors of about 2⁴ (the state integration and the Hilbert operator are
    both of order 4, docs/steady.md); the command prints and stores the same levels."""
    from slippulse.core.h5io import write_pulse
    from slippulse.steady.continuation.gridcheck import grid_convergence, observed_order
    from slippulse.steady.solver import solve_pulse
    sol = solve_pulse(params, 1.2, n_points=500)
    assert sol.stats.converged
    rows = grid_convergence(params, sol, levels=2)
    assert [r.n for r in rows] == [500, 999, 1997] and all(r.converged for r in rows)
    p_beta, p_L = observed_order(rows)
    assert 3.5 < p_beta < 4.5 and 3.5 < p_L < 4.5
    assert abs(rows[2].dL_rel) < abs(rows[1].dL_rel) / 10
    import cli_inproc
    path = str(tmp_path / "one.h5")
    write_pulse(path, sol.to_pulse(), params)
    r = cli_inproc.run(["steady", "grid-convergence", path, "--labels", "td1.2000", "--write",
                        "-q"])
    assert r.returncode == 0, r.stderr
    p, _ = read_pulse(path, "td1.2000")
    assert list(p.extra["grid_convergence_n"]) == [500, 999, 1997]
    assert np.allclose(p.extra["grid_convergence_dL_rel"], [r.dL_rel for r in rows], rtol=1e-6)
    assert p.extra["grid_convergence_order_L"] == pytest.approx(p_L, rel=1e-6)
    r = cli_inproc.run(["steady", "grid-convergence", path, "--labels", "td9.9", "-q"])
    assert r.returncode == 2 and "--labels" in r.stderr and "Traceback" not in r.stderr
    r = cli_inproc.run(["steady", "grid-convergence", path, "--labels", "td1.2000",
                        "--levels", "9", "-q"])
    assert r.returncode == 2 and "--levels=9 is invalid" in r.stderr
    # --adapted: the pulse re-laid on an adapted grid of 400 first, and that one refined (one
    # level: 400 → 799), the stored pulse left alone
    r = cli_inproc.run(["steady", "grid-convergence", path, "--labels", "td1.2000",
                        "--levels", "1", "--adapted", "400", "-q"])
    assert r.returncode == 0, r.stderr
    lines = [ln.split() for ln in r.stdout.splitlines()
             if ln.startswith("td1.2000 1.") and len(ln.split()) == 8]
    assert [int(ln[2]) for ln in lines] == [400, 799]
    assert abs(float(lines[0][3]) / rows[0].beta - 1) < 1e-3        # the same pulse, re-laid
    p2, _ = read_pulse(path, "td1.2000")
    assert list(p2.extra["grid_convergence_n"]) == [500, 999, 1997]
    for bad, word in ((["--adapted", "10"], "--adapted=10 is invalid"),
                      (["--adapted", "400", "--write"], "--write with --adapted")):
        r = cli_inproc.run(["steady", "grid-convergence", path, "--labels", "td1.2000", *bad,
                            "-q"])
        assert r.returncode == 2 and word in r.stderr
