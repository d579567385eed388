"""What the deep march reuses from one pulse to the next (stop 44): the corrector's LU for the
next tangent and the next corrector (``DeepSettings.reuse_lu``), and the last grid check's fine
pulse and LU for the next check (``check_pulse(warm=...)``). Same pulses and checks as without,
to the solver's tolerance; and the reuse does happen."""
import math

import numpy as np
import pytest

from slippulse.steady.continuation import DeepMarch, DeepSettings, GridTolerance
from slippulse.steady.continuation.arclength import (family_tangent, tangent_by_refinement,
                                                     unit_tangent)
from slippulse.steady.continuation.gridcheck import check_grid_2n, check_pulse

DS = 0.001


@pytest.fixture(scope="module")
def start(params):
    from slippulse.steady.solver import solve_pulse
    a = solve_pulse(params, 1.2, n_points=500)
    return (a.xi, a.x[:-1], a.beta, 1.2)


def _march(params, start, reuse, steps, chord=True):
    m = DeepMarch(params, start, settings=DeepSettings(ds=DS, ds_max=DS, ds_min=0.25 * DS,
                                                       max_iter=20, stretch=True,
                                                       predictor="secant", reuse_lu=reuse,
                                                       chord=chord and reuse))
    rows = []
    for _ in range(steps):
        m.ds = DS
        assert m.step() is None
        rows.append((m.sol.x.copy(), m.sol.stats.iterations, m.sol.stats.chord_iterations))
    return m, rows


def test_the_march_reuses_its_lu_and_finds_the_same_pulses(params, start):
    m0, plain = _march(params, start, False, 4)
    m1, reuse = _march(params, start, True, 4)
    # the tangent alone by refinement (the "auto" march's default): the same steps, iteration
    # for iteration
    m2, tangent_only = _march(params, start, True, 4, chord=False)
    assert [r[1:] for r in tangent_only] == [r[1:] for r in plain]
    assert m2._lu is not None and m0._lu is None
    for (x0, _, _), (x2, _, _) in zip(plain, tangent_only):
        assert np.max(np.abs(x2 - x0)) < 1e-10
    for (x0, _, _), (x1, _, _) in zip(plain, reuse):
        assert x0.size == x1.size and np.max(np.abs(x1 - x0)) < 1e-10
    # without reuse every step forms Jacobians; with it, steps after the first converge by chord
    # iterations with the last LU, no Newton iteration at all
    assert all(it > 0 and ch == 0 for _, it, ch in plain)
    assert reuse[0][1] > 0
    assert all(it == 0 and ch > 0 for _, it, ch in reuse[1:])
    assert m1.n_iterations < m0.n_iterations
    # the tangent by refinement with the kept LU is the directly solved one
    n1 = m1._tangent()
    n0 = family_tangent(m1._base, m1._x, m1._orient)
    assert np.max(np.abs(n1 - n0)) < 1e-9 * np.max(np.abs(n0))
    # replace/restart drop what was kept (another grid): the next tangent is solved directly
    m1.replace(m1.sol)
    assert m1._lu is None and m1._n is None


def test_tangent_by_refinement_converges_or_says_none(params, start):
    m, _ = _march(params, start, True, 2)
    A = m._arc.residual_and_jacobian(m._x)[1]
    n = tangent_by_refinement(A, m._lu)
    assert n is not None
    ref = family_tangent(m._base, m._x, m._orient)
    assert np.max(np.abs(unit_tangent(n, m.beta, m.kappa) - ref)) < 1e-9 * np.max(np.abs(ref))
    # the LU of a matrix too far from A (half its columns scaled by 0.3: the refinement's error
    # there is multiplied by 1 − 1/0.3 per step) → None, and the march solves A directly
    import scipy.linalg as sla
    B = A.copy()
    B[:, : A.shape[0] // 2] *= 0.3
    assert tangent_by_refinement(A, sla.lu_factor(B)) is None
    # ... and one near enough (by 0.9: 1 − 1/0.9 = −0.11) converges to the same tangent
    B = A.copy()
    B[:, : A.shape[0] // 2] *= 0.9
    n2 = tangent_by_refinement(A, sla.lu_factor(B))
    assert np.max(np.abs(unit_tangent(n2, m.beta, m.kappa) - ref)) < 1e-9 * np.max(np.abs(ref))


def test_a_warm_grid_check_is_the_cold_one(params, start):
    """The check of a later pulse on the same deformed grid, started from the earlier check's fine
    pulse (transported) and LU: the same fine pulse and figures as from the interpolated start,
    with fewer iterations; a warm start that does not fit the grid is ignored."""
    loose = GridTolerance(beta=1e-3, L=1e-2)
    m, _ = _march(params, start, True, 2)
    first = check_pulse(params, m.sol, loose, warm=())
    assert first.passed and first.warm is not None
    assert check_pulse(params, m.sol, loose).warm is None        # no chain asked for
    for _ in range(2):
        m.ds = DS
        assert m.step() is None
    n = m.sol.xi.size
    cold, db0, dl0 = check_grid_2n(params, m.sol, n, nested=True, stages=4, max_iter=15)
    warm, db1, dl1 = check_grid_2n(params, m.sol, n, nested=True, stages=4, max_iter=15,
                                   warm=first.warm)
    assert cold.stats.converged and warm.stats.converged
    assert np.max(np.abs(warm.x - cold.x)) < 1e-9
    assert db1 == pytest.approx(db0, abs=1e-12) and dl1 == pytest.approx(dl0, abs=1e-10)
    assert warm.stats.history[0] < 0.5 * cold.stats.history[0]
    # (measured: 1 Newton + 3 chord iterations against 1 + 5; deep in the family, where the
    # front moves by a few cells between checks, far fewer: BENCHMARKS.md "Stop 44")
    assert (warm.stats.iterations + warm.stats.chord_iterations
            < cold.stats.iterations + cold.stats.chord_iterations)
    assert warm.stats.lu is not None and cold.stats.lu is None
    # a warm start of another grid size changes nothing
    x0, xf0, lu = first.warm
    other, db2, dl2 = check_grid_2n(params, m.sol, n, nested=True, stages=4, max_iter=15,
                                    warm=(x0[1:], xf0, lu))
    assert other.stats.history[0] == cold.stats.history[0]
    assert (db2, dl2) == (db0, dl0)


class _TangentFails(DeepMarch):
    """A march whose tangent-predicted steps above ``predictor_ds_max`` fail (as they do deep in
    the family, where they take ``max_iter`` iterations to do so); the length/secant steps below
    it are the real ones."""

    def _attempt(self):
        res = super()._attempt()
        if self.last_predictor == "tangent" and self.ds > self.settings.predictor_ds_max:
            return (False, None, "failed (forced)") + res[3:]
        return res


@pytest.mark.parametrize("hold", [False, True])
def test_hold_keeps_ds_where_the_secant_works(params, start, hold):
    """``DeepSettings.hold``: after a tangent step above predictor_ds_max failed and a secant step
    below it passed, ds is capped there: one failure in six steps instead of one every time ds
    grows past the threshold."""
    s = DeepSettings(ds=DS, ds_max=10 * DS, ds_min=0.1 * DS, max_iter=20, stretch=True,
                     predictor="secant", predictor_ds_max=1.2 * DS, hold=hold)
    m = _TangentFails(params, start, settings=s)
    for _ in range(6):
        assert m.step() is None
    assert m.held is hold
    if hold:
        assert m.n_failed == 1 and m.ds <= s.predictor_ds_max
    else:
        assert m.n_failed >= 2


def test_chord_once_held_keeps_the_path(params, start):
    """``DeepSettings.chord_held``: once held, the correctors start with chord iterations on the
    last LU; ds is capped, so the march takes the same steps to the same pulses."""
    runs = {}
    for chord_held in (False, True):
        s = DeepSettings(ds=DS, ds_max=10 * DS, ds_min=0.1 * DS, max_iter=20, stretch=True,
                         predictor="secant", predictor_ds_max=1.2 * DS, hold=True,
                         chord_held=chord_held)
        m = _TangentFails(params, start, settings=s)
        rows = []
        for _ in range(6):
            assert m.step() is None
            rows.append((m.ds, m.sol.x.copy(), m.sol.stats.chord_iterations))
        runs[chord_held] = (m, rows)
    (m0, plain), (m1, chord) = runs[False], runs[True]
    assert m0.held and m1.held
    assert [r[0] for r in plain] == [r[0] for r in chord]
    for (_, x0, _), (_, x1, _) in zip(plain, chord):
        assert x0.size == x1.size and np.max(np.abs(x1 - x0)) < 1e-10
    assert all(c == 0 for _, _, c in plain)
    assert sum(c > 0 for _, _, c in chord) >= 3       # the held steps start with chords
    assert m1.n_iterations < m0.n_iterations


def test_creep_only_once_held_and_near_the_cap(params, start, monkeypatch):
    """``DeepSettings.creep_held``: the correctors stop creeping Newton after that many
    iterations (``newton(creep=...)``) only once the march is held and ds is within
    ``cap_shrink`` of the cap; before, and below it (after a halving), ``creep`` as set (0).
    ``natural_held``: the correctors' line search is "natural" once held, at any ds, and
    ``line_search`` ("residual") before."""
    from slippulse.steady.continuation import deep
    seen, searches = [], []
    real = deep.newton
    box = {}

    def newton(*a, **k):
        m = box["m"]
        seen.append((k["creep"], m.held, m.ds >= 0.8 * m.cap * (1 - 1e-9)))
        searches.append((k["line_search"], m.held))
        return real(*a, **k)

    monkeypatch.setattr(deep, "newton", newton)
    s = DeepSettings(ds=DS, ds_max=10 * DS, ds_min=0.1 * DS, max_iter=20, stretch=True,
                     predictor="secant", predictor_ds_max=1.2 * DS, hold=True, creep_held=4,
                     cap_shrink=0.8, cap_grow_after=3, natural_held=True)
    m = box["m"] = _CapFails(params, start, settings=s)
    for _ in range(10):
        assert m.step() is None
    assert all(c == (4 if held and near else 0) for c, held, near in seen), seen
    assert all(ls == ("natural" if held else "residual") for ls, held in searches), searches
    assert any(h and n for _, h, n in seen) and any(h and not n for _, h, n in seen)
    assert not seen[0][1] and m.held


class _CapFails(_TangentFails):
    """As _TangentFails, and once held every attempt with ds above ``limit`` fails (the basin
    of the held steps deep in the family, measured: 0.002 failed one attempt in three)."""
    limit = 1.0 * DS

    def _attempt(self):
        if self.held and self.ds > self.limit * (1 + 1e-9):
            return False, None, "failed (forced, held)", (math.nan, math.nan), self.q
        return super()._attempt()


@pytest.mark.parametrize("shrink", [1.0, 0.8])
def test_the_held_cap_lowers_itself_after_failures_at_it(params, start, shrink):
    """``DeepSettings.cap_shrink``: once held, a failed attempt at the cap lowers it, so the
    march stops failing there; with a fixed cap (1.0) it fails there again and again."""
    s = DeepSettings(ds=DS, ds_max=10 * DS, ds_min=0.1 * DS, max_iter=20, stretch=True,
                     predictor="secant", predictor_ds_max=1.2 * DS, hold=True,
                     cap_shrink=shrink, cap_grow_after=100)
    m = _CapFails(params, start, settings=s)
    for _ in range(10):
        assert m.step() is None
    assert m.held
    failed_held = m.n_failed - 1                 # the first failure is the tangent's (held then)
    if shrink == 1.0:
        assert m.cap == s.predictor_ds_max and failed_held >= 3
    else:
        assert failed_held == 1 and m.cap <= 0.8 * s.predictor_ds_max + 1e-15


class _CapFailsOnce(_CapFails):
    """As _CapFails, but only the first held attempt above ``limit`` fails."""

    def _attempt(self):
        if self.held and self.ds > self.limit * (1 + 1e-9) and not getattr(self, "_done", False):
            self._done = True
            return False, None, "failed (forced, held)", (math.nan, math.nan), self.q
        return DeepMarch._attempt(self) if self.held else _TangentFails._attempt(self)


def test_the_held_cap_grows_back_after_steps_at_it(params, start):
    """After ``cap_grow_after`` accepted steps at the lowered cap it is raised by 1/cap_shrink,
    never above predictor_ds_max."""
    s = DeepSettings(ds=DS, ds_max=10 * DS, ds_min=0.1 * DS, max_iter=20, stretch=True,
                     predictor="secant", predictor_ds_max=1.2 * DS, hold=True,
                     cap_shrink=0.8, cap_grow_after=2)
    m = _CapFailsOnce(params, start, settings=s)
    caps = []
    for _ in range(9):
        assert m.step() is None
        caps.append(m.cap)
    assert min(caps) <= 0.8 * s.predictor_ds_max + 1e-15
    assert caps[-1] == s.predictor_ds_max and max(caps) == s.predictor_ds_max


@pytest.mark.slow
def test_the_held_corrector_at_9_5_km_converges_with_the_natural_line_search():
    """The real case behind ``natural_held`` (stop 47): the march resumed from the committed
    9.47 km seed (held, N = 6614) reaches the corrector of its second step, ds = 0.00064, which
    failed after 25 iterations with the ‖r‖₂ line search. With the natural one it converges from
    the same guess within 12 iterations, to a pulse near the guess (β and τ_d/τ_min within 1e−7).
    ≈ 2.5 min on two threads (the capture, then one corrector)."""
    import importlib.util
    import os
    from slippulse.steady.newton import newton
    path = os.path.join(os.path.dirname(__file__), os.pardir, "benchmarks",
                        "bench_line_search_held.py")
    spec = importlib.util.spec_from_file_location("bench_line_search_held", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    box = mod.capture(os.path.join(os.path.dirname(path), os.pardir, "steady", "seeds",
                                   "deep_seed_s46.h5"))
    assert box["problem"].ds == pytest.approx(0.00064) and box["problem"].base.n == 6614
    x, st = newton(box["problem"], box["x0"], tol=1e-13, max_iter=12, line_search="natural")
    assert st.converged, st.message
    assert abs(x[-2] - box["x0"][-2]) < 1e-7 and abs(x[-1] - box["x0"][-1]) < 1e-7
