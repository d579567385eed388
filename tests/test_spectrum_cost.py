"""The cost of the family's spectrum: what each saving changes, and
that it changes nothing else. The slope product and the fused assembly against independent
numpy forms of the same matrices; Newton's vector finished with the factor in hand; a clip that
failed on the pulse above not tried again; the mapped re-solves reuse their LU."""
import math

import numpy as np
import pytest

from slippulse.spectrum import eigensolve as es


def _dense_slopes(xi):
    """S with S u = slopes of the natural cubic spline, column by column from spline_slopes."""
    from slippulse.steady.hilbert import spline_slopes
    n = xi.size
    return np.column_stack([spline_slopes(xi, np.eye(n)[:, k]) for k in range(n)])


@pytest.mark.parametrize("n", [4, 9, 301])
def test_add_times_slopes_is_B_times_the_slope_matrix(n):
    from slippulse.steady.hilbert import add_times_slopes
    rng = np.random.default_rng(n)
    xi = np.cumsum(rng.uniform(1e-3, 2.0, n))          # spacing ratios up to 2000
    S = _dense_slopes(xi)
    B = rng.standard_normal((n + 3, n))
    Bc = B + 1j * rng.standard_normal(B.shape)
    out0 = rng.standard_normal((n + 3, n))
    scale = np.abs(B) @ np.abs(S)
    got = add_times_slopes(out0.copy(), B, xi)
    assert np.max(np.abs(got - (out0 + B @ S)) / (1.0 + scale)) < 1e-13
    got = add_times_slopes(out0.astype(complex), Bc, xi)
    assert np.max(np.abs(got - (out0 + Bc @ S)) / (1.0 + scale)) < 1e-13
    got = add_times_slopes(np.zeros((n + 3, n), complex), B, xi)     # real B, complex out
    assert np.max(np.abs(got - B @ S) / (1.0 + scale)) < 1e-13
    with pytest.raises(TypeError):
        add_times_slopes(np.zeros((n + 3, n)), Bc, xi)


def _reference_matrices(op, sigma, deriv=True):
    """M(σ), M′(σ) of the operator from its parts with numpy products (the assembly without the
    fused rows): X = λW + (λσ/πc)H + (λγ/π)H₀, X D by times_D4."""
    from slippulse.spectrum.kernels import times_D4
    el = op.elastic
    lam, c, n = el.lam, op.c, op.n
    cplx = complex(sigma).imag != 0.0
    dt = complex if cplx else float
    s_ = complex(sigma) if cplx else float(np.real(sigma))
    Phi, dPhi = op._state(s_, np.eye(n, dtype=dt), True)
    M = op.fphi[:, None] * Phi + op.phi_correction
    M[np.diag_indices(n)] += op.fv
    M = M + (lam / (math.pi * c)) * el.H
    dM = op.fphi[:, None] * dPhi
    if s_ != 0.0:
        W, dW = el.kernel_matrices(s_, True)
        X = lam * W + (lam * s_ / (math.pi * c)) * el.H + (lam * el.gamma(s_) / math.pi) * el.H0
    else:
        X, dW = np.zeros((n, n), dt), np.zeros((n, n), dt)
    dX = lam * dW + (lam / (math.pi * c)) * el.H + (lam * el.gamma(1.0) / math.pi) * el.H0
    a, B, da, dB = op._slip(s_)
    XD, dXD = np.empty((n, n), dt), np.empty((n, n), dt)
    times_D4(X.astype(dt), dX.astype(dt), a, B, op.cells[1], da, dB, XD, dXD, True)
    M = (M - XD) / op.tau_d
    if op.pin is not None:
        M = M - np.outer(op.pin[0], op.pin[1])
    return M, (dM - dXD) / op.tau_d


@pytest.mark.parametrize("pin", [False, True])
def test_the_fused_assembly_equals_the_assembly_from_its_parts(pulse12, params, pin):
    from slippulse.spectrum.operators import StabilityOperator
    op = StabilityOperator(pulse12.to_pulse(), params, pin_translation=pin)
    u = op.rate_unit
    for sigma in (0.0, 0.37 * u, (5.0 + 2.0j) * u):
        M, dM = op.matrices(sigma)
        R, dR = _reference_matrices(op, sigma)
        assert M.dtype == R.dtype and dM.dtype == dR.dtype
        assert np.max(np.abs(M - R)) <= 1e-14 * np.max(np.abs(R))
        assert np.max(np.abs(dM - dR)) <= 1e-14 * np.max(np.abs(dR))
        M1, none = op.matrices(sigma, deriv=False)
        assert none is None and np.array_equal(M1, M)


class _Pencil:
    """M(σ) = A − σ I, A tridiagonal with a leading eigenvalue near 1 whose vector decays by
    ten decades per ten rows, as the pulse's unstable mode far behind the pulse (|V₁| ≈ 1e-21
    there against 1e-1 at the front), counting its assemblies."""

    def __init__(self, n=40):
        self.A = (np.diag(np.r_[1.0, np.full(n - 1, 3.0)]) + np.diag(np.full(n - 1, 0.2), -1)
                  + np.diag(np.full(n - 1, 0.05), 1))
        w, V = np.linalg.eig(self.A)
        k = int(np.argmin(np.abs(w - 1.0)))
        self.lam, self.v1 = float(w[k].real), V[:, k].real
        self.n, self.rate_unit, self.calls = n, 1.0, 0

    def matrices(self, sigma, deriv=True):
        self.calls += 1
        return self.A - sigma * np.eye(self.n), -np.eye(self.n)


def test_newton_finishes_the_vector_with_the_factor_in_hand(monkeypatch):
    """σ within the step criterion, the vector not: noise of 1e-30 where the mode is below it
    (a mode interpolated from a coarser level: measured on the deep pulses, the backward error
    after the first step is 1e-5 at rows where |V₁| ≈ 1e-21). The next solves reuse the factor
    of M(σ_0): one assembly, where Newton without them (FROZEN_SOLVES = 0) needs two; the same σ, and the true backward error below the tolerance."""
    rng = np.random.default_rng(0)
    op = _Pencil()
    x0 = op.v1.copy()
    x0[20:] += 1e-30 * rng.standard_normal(op.n - 20)
    e = es.newton_eigen(op, op.lam + 4e-7, x0, tol=1e-6)
    assert e.converged, e.message
    assert op.calls == 1
    assert abs(e.sigma - op.lam) < 1e-13
    true = es.relres(op.matrices(e.sigma)[0], e.V)
    assert true < 1e-6 and abs(e.residual - true) < 1e-9 + 1e-3 * true
    monkeypatch.setattr(es, "FROZEN_SOLVES", 0)
    op.calls = 0
    old = es.newton_eigen(op, op.lam + 4e-7, x0, tol=1e-6)
    assert old.converged and op.calls == 2 and abs(old.sigma - e.sigma) < 1e-13


def test_frozen_solves_stop_when_sigma_leaves_the_criterion():
    """Inverse iteration on the linearisation may only finish a vector: where σ moves beyond the
    step criterion it hands back to Newton (not converged), with its new σ."""
    op = _Pencil()
    s0 = op.lam + 4e-7
    M, dM = op.matrices(s0)
    x = op.v1 + 1e-3
    e = x / np.vdot(x, x)
    hist = []
    sig, _, _, ok = es.frozen_solves(es.Factor(M), M, dM, e, x / np.vdot(e, x), s0, 1.0,
                                      1e-12, 1e-6, hist)
    assert not ok and abs(sig - s0) > 1e-12 and hist == []


def test_a_clip_that_failed_on_the_pulse_above_is_not_tried_again(tmp_path, pulse12, params,
                                                                  monkeypatch):
    """Level 0 goes straight to the pulse's own N where the neighbour above, of the same own N,
    had its ladder start there (its clip failed): the deep pulses skip a re-solve bound to give
    up. Where the neighbour's ladder started below its own N, or at another N, the clip is tried.
    The attempts follow LEVEL0_ATTEMPTS, and the one that held is recorded with the result."""
    from slippulse.spectrum import family as sf
    p = pulse12.to_pulse()
    tried = []
    real = sf.solve_level0

    def level0(pulse, prm, gmap, n0, creep=0):
        tried.append(n0)
        return real(pulse, prm, gmap, n0, creep)

    monkeypatch.setattr(sf, "solve_level0", level0)
    s = sf.SpectrumSettings(levels=0, min_points=0, max_points=500, extra=False, tol=1e-6,
                            target=None, rel_target=0.0)
    unit = p.c_p / p.L
    guess = np.array([22.65 * unit])

    def tracking(ladder):
        return sf.Tracking(guess, unit, ladder)

    for ladder, expect in (({700: 22.6, 990: 22.65}, [700]),     # its clip failed: own N
                           ({500: 22.6, 707: 22.65}, [500]),     # its clip held: clip
                           ({1000: 22.6, 1414: 22.65}, [500]),   # another own N: clip
                           ({}, [500])):                         # no ladder: clip
        tried.clear()
        res, after = sf.pulse_task(p.label, p, params, tracking(ladder), s)
        assert tried == expect, (ladder, tried)
        assert res.status == "converged" and res.n_points == expect[0]
        assert res.leading.real / res.rate_unit == pytest.approx(22.65, rel=0.03)
        assert f"N = {expect[0]}" in res.level0_attempt
        assert after.sigmas[0] == res.sigmas[0] and after.tau == pytest.approx(1.2)
    assert sf.NO_TRACKING.clip_failed_above(700, p, 1) is False

    def failing_where(fails):
        """A level 0 that records each (N, creep) tried and fails where fails(N, creep)."""
        def level0_mock(pulse, prm, gmap, n0, creep=0):
            tried.append((n0, creep))
            if fails(n0, creep):
                return pulse, f"did not converge at {n0}/{creep}"
            return real(pulse, prm, gmap, n0, creep)
        return level0_mock

    # where the own N fails (creeping, as at 6.3-6.6 km), the clip is the fallback
    monkeypatch.setattr(sf, "solve_level0", failing_where(lambda n0, creep: n0 == 700))
    tried.clear()
    res, _ = sf.pulse_task(p.label, p, params, tracking({700: 22.6}), s)
    assert tried == [(700, sf.LEVEL0_CREEP), (500, sf.LEVEL0_CREEP)]
    assert res.status == "converged" and res.n_points == 500
    assert res.level0_attempt == f"level 0 on the clipped N = 500 (creep stop {sf.LEVEL0_CREEP})"

    # where the clip fails too, the own N without the creep stop is the last resort (a slow
    # convergence, as at 6.0 km)
    monkeypatch.setattr(sf, "solve_level0", failing_where(lambda n0, creep: creep or n0 == 500))
    tried.clear()
    res, _ = sf.pulse_task(p.label, p, params, tracking({700: 22.6}), s)
    assert tried == [(700, sf.LEVEL0_CREEP), (500, sf.LEVEL0_CREEP), (700, 0)]
    assert res.status == "converged" and res.n_points == 700

    # the clip without the creep stop is the last resort, after the own N without it (at
    # 6.57 km the clip converges so, in 27 iterations, and the own N does not in 60)
    monkeypatch.setattr(sf, "solve_level0", failing_where(lambda n0, creep: creep or n0 == 700))
    tried.clear()
    res, _ = sf.pulse_task(p.label, p, params, tracking({700: 22.6}), s)
    assert tried == [(700, sf.LEVEL0_CREEP), (500, sf.LEVEL0_CREEP), (700, 0), (500, 0)]
    assert res.status == "converged" and res.n_points == 500
    monkeypatch.setattr(sf, "solve_level0", failing_where(lambda n0, creep: True))
    before = tracking({700: 22.6})
    res, after = sf.pulse_task(p.label, p, params, before, s)
    assert res.status == "failed" and "700/4" in res.message and "500/4" in res.message \
        and "500/0" in res.message and "700/0" in res.message
    assert after is before                       # a failed pulse leaves the tracking as it was


def test_mapped_resolves_reuse_their_LU_and_reach_the_same_pulse(pulse12, params, monkeypatch):
    """The ladder's re-solves run chord iterations with each full step's LU (newton reuse=True):
    fewer factorisations, the same tolerance, the same pulse to 1e-12."""
    import scipy.linalg as sla

    from slippulse.spectrum.refine import mapped_pulse
    from slippulse.steady import newton as nw
    from slippulse.steady import solver
    from slippulse.steady.grid import GridMap
    p = pulse12.to_pulse()
    gmap = GridMap(p.xi)
    count = [0]
    real = sla.lu_factor

    def spy(*a, **k):
        count[0] += 1
        return real(*a, **k)
    monkeypatch.setattr(nw.sla, "lu_factor", spy)
    sol = mapped_pulse(params, p, gmap, 990)
    n_reuse = count[0]
    count[0] = 0
    ref = solver.resolve_on_grid(params, p, gmap(990), state_order=4)
    assert sol.stats.converged and ref.stats.converged
    assert n_reuse < count[0], (n_reuse, count[0])
    q, r = sol.to_pulse(), ref.to_pulse()
    assert abs(q.beta - r.beta) < 1e-12 and abs(q.L - r.L) < 1e-10 * r.L
    assert np.max(np.abs(np.log(q.v) - np.log(r.v))) < 1e-10


# ---- the re-solves' line search, the ladder's starts, the start vector, the heap ----

class _Steep:
    """Three unknowns (two like ln v, the last like β) and equations of very different steepness,
    each row weighted by w (the same solution for every w)."""

    def __init__(self, w):
        self.w = np.asarray(w, float)

    def _f(self, x):
        y0, y1, b = x
        return np.array([np.exp(3 * y0) - 20.0 + b, np.exp(y1) - np.exp(y0) - 0.5, b - 0.1 * y1])

    def _j(self, x):
        y0, y1, b = x
        return np.array([[3 * np.exp(3 * y0), 0.0, 1.0], [-np.exp(y0), np.exp(y1), 0.0],
                         [0.0, -0.1, 1.0]])

    def residual(self, x):
        return self.w * self._f(x)

    def residual_and_jacobian(self, x):
        return self.w * self._f(x), self.w[:, None] * self._j(x)

    def valid(self, x):
        return True


def test_the_natural_line_search_does_not_depend_on_how_the_equations_are_scaled():
    """Deuflhard's natural monotonicity test judges a step by the Newton correction J⁻¹r, which
    a row scaling of the equations leaves unchanged: the same iterates whatever the weights.
    The ‖r‖₂ test depends on them (here 7, 27 and 38 iterations from one start): a few steep
    equations, as at the healing front of a re-solved deep pulse, cut every step."""
    from slippulse.steady import newton as nw
    x0 = np.array([-1.863, -1.276, -0.424])
    runs = {}
    for ls in ("natural", "residual"):
        for w in ((1.0, 1.0, 1.0), (1e-4, 1.0, 1.0), (1.0, 1e4, 1.0)):
            xs = []
            x, st = nw.newton(_Steep(w), x0, tol=1e-11 * max(w), line_search=ls,
                              callback=lambda k, x, m: xs.append(x.copy()))
            assert st.converged, (ls, w, st.message)
            runs[ls, w] = (st.iterations, np.array(xs), x)
    nat = [runs[k] for k in runs if k[0] == "natural"]
    for its, xs, x in nat[1:]:
        assert its == nat[0][0]
        assert np.max(np.abs(xs - nat[0][1])) < 1e-12
        assert np.max(np.abs(x - nat[0][2])) < 1e-12
    res_its = [runs[k][0] for k in runs if k[0] == "residual"]
    assert max(res_its) > 3 * nat[0][0], res_its          # the test the natural one replaces
    with pytest.raises(ValueError, match="line_search"):
        nw.newton(_Steep((1, 1, 1)), x0, line_search="armijo")


class _TwoNear(_Pencil):
    """M(σ) = A − σ I with the leading eigenvalue 1 and a second one at 1.1 (as near the
    imaginary axis the deep pulses' continuum lies near their small rate)."""

    def __init__(self, n=12):
        rng = np.random.default_rng(3)
        Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
        w = np.r_[1.0, 1.1, np.linspace(3.0, 5.0, n - 2)]
        self.A = Q @ np.diag(w) @ Q.T
        self.Q = Q
        self.lam, self.v1 = 1.0, Q[:, 0]
        self.n, self.rate_unit, self.calls = n, 1.0, 0


def test_a_purified_start_vector_makes_the_first_step_second_order():
    """From σ₀ 3 % off and a vector with a 30 % part of the neighbouring eigenvalue's mode, the
    first Newton step lands far off (the vector misleads it); after inverse-iteration solves
    with the first factor it lands O(|σ₀ − σ*|²) away, and Newton needs fewer assemblies.
    The same eigenvalue either way."""
    op = _TwoNear()
    x0 = op.Q[:, 0] + 0.3 * op.Q[:, 1]
    plain = es.newton_eigen(op, 1.03, x0, tol=1e-10)
    calls_plain = op.calls
    op.calls = 0
    pure = es.newton_eigen(op, 1.03, x0, tol=1e-10, purify=es.PURIFY_SOLVES)
    assert plain.converged and pure.converged
    assert abs(plain.sigma - 1.0) < 1e-12 and abs(pure.sigma - 1.0) < 1e-12
    first_plain, first_pure = abs(plain.history[0] - 1.0), abs(pure.history[0] - 1.0)
    assert first_pure < 0.1 * first_plain, (first_pure, first_plain)
    assert first_pure < 10 * 0.03 ** 2
    assert op.calls < calls_plain, (op.calls, calls_plain)


def test_the_ladder_start_is_extrapolated_from_the_two_pulses_before():
    """Newton's start at each level: the neighbour's value moved linearly in τ_d through the
    pulse before it, where both have the level and the steps are alike; else the neighbour's."""
    from slippulse.spectrum.family import EXTRAPOLATE_RATIO, NO_TRACKING, Tracking

    def s(t, n):                                     # a smooth family, one law per level
        return 1e-4 * (1.0 + 50.0 * (t - 1.0086)) * (1.0 + 1e3 / n) + 3.0 * (t - 1.0086) ** 2

    t2, t1, t0 = 1.008610, 1.008606, 1.008602
    older = {3542: s(t2, 3542), 5009: s(t2, 5009)}
    ladder = {3542: s(t1, 3542), 5009: s(t1, 5009), 7083: 1.0}
    prev = Tracking(np.zeros(1, complex), 1.0, ladder, t1, (t2, older))
    got = prev.predicted_ladder(t0)
    for n in (3542, 5009):
        assert abs(got[n] - s(t0, n)) < 1e-2 * abs(ladder[n] - s(t0, n))   # O(h²) vs O(h)
    assert got[7083] == 1.0                          # no level 7083 before: the neighbour's
    far = t1 - (EXTRAPOLATE_RATIO + 0.5) * (t2 - t1)
    assert prev.predicted_ladder(far) == ladder      # a step too long: no extrapolation
    back = t1 + 0.5 * (t2 - t1)
    assert prev.predicted_ladder(back) == ladder     # turned back: none
    stored = Tracking(np.zeros(1, complex), 1.0, ladder)    # tracked from a stored spectrum
    assert stored.predicted_ladder(t0) == ladder
    assert NO_TRACKING.predicted_ladder(t0) == {}
    # the state after a pulse carries this one's ladder as the one before
    assert prev.before[1] is older


def test_keep_freed_memory_lets_a_freed_array_reuse_its_pages():
    """After keep_freed_memory() a 200 MB array freed and allocated again takes its pages from
    the heap (few page faults); without, glibc hands it back to the system and the next one
    faults every page in again (the 14 % system time of the 271-pulse run)."""
    import subprocess
    import sys
    if not sys.platform.startswith("linux"):
        pytest.skip("glibc's mallopt")
    code = """
import resource, sys
import numpy as np
from slippulse.core.memory import keep_freed_memory
ok = keep_freed_memory() if sys.argv[1] == '1' else True
a = np.ones(25_000_000); del a
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
a = np.ones(25_000_000); del a
print(int(ok), resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""
    out = {}
    for flag in ("0", "1"):
        r = subprocess.run([sys.executable, "-c", code, flag], capture_output=True, text=True,
                           check=True)
        ok, faults = map(int, r.stdout.split())
        if not ok:
            pytest.skip("no glibc mallopt here")
        out[flag] = faults
    pages = 200e6 / 4096
    assert out["1"] < 0.05 * pages, out
    assert out["0"] > 5 * out["1"], out


def test_a_mapped_resolve_falls_back_to_the_residual_line_search(pulse12, params, monkeypatch):
    """Where the natural line search does not converge (at 6.70 km it stalled at max|r| =
    1.2e−5), the re-solve is made again with the ‖r‖₂ test; where both fail, the message says
    both, and the solution is marked not converged."""
    from slippulse.spectrum import refine
    from slippulse.steady import solver
    from slippulse.steady.grid import GridMap
    p = pulse12.to_pulse()
    gmap = GridMap(p.xi)
    real = solver.resolve_on_grid
    seen = []

    def natural_fails(*a, line_search="residual", **k):
        seen.append(line_search)
        sol = real(*a, line_search=line_search, **k)
        if line_search == "natural":
            sol.stats.converged, sol.stats.message = False, "line search failed (mock)"
        return sol

    monkeypatch.setattr(solver, "resolve_on_grid", natural_fails)
    sol = refine.mapped_pulse(params, p, gmap, 707)
    assert seen == ["natural", "residual"] and sol.stats.converged
    seen.clear()
    monkeypatch.setattr(solver, "resolve_on_grid", lambda *a, line_search="residual", **k: (
        seen.append(line_search), _unconverged(real(*a, line_search=line_search, **k),
                                               line_search))[1])
    sol = refine.mapped_pulse(params, p, gmap, 707)
    assert seen == ["natural", "residual"] and not sol.stats.converged
    assert "mock residual" in sol.stats.message and "mock natural" in sol.stats.message


def _unconverged(sol, tag):
    sol.stats.converged, sol.stats.message = False, f"mock {tag}"
    return sol
