"""What the deep march reuses from one pulse to the next: the corrector's LU for the next tangent
and the next corrector (``NewtonCorrector.reuse_lu``, ``chord``), and the last grid check's fine
pulse and LU for the next check (``check_pulse(warm=...)``). Same pulses and checks as without,
to the solver's tolerance; and the reuse does happen. Also the held step control
(:class:`HeldSteps`): its cap, and its corrector."""
import dataclasses
import math

import numpy as np
import pytest

from slippulse.steady.continuation import (Continuation, FreeSteps, GridTolerance, HeldSteps,
                                           NewtonCorrector, SecantPredictor, Strategy,
                                           StretchGrid)
from slippulse.steady.continuation.arclength import (family_tangent, tangent_by_refinement,
                                                     unit_tangent)
from slippulse.steady.continuation.gridcheck import check_grid_2n, check_pulse
from slippulse.steady.newton import DirectLU

DS = 0.001


@pytest.fixture(scope="module")
def start(params):
    from slippulse.steady.solver import solve_pulse
    a = solve_pulse(params, 1.2, n_points=500)
    return (a.xi, a.x[:-1], a.beta, 1.2)


GRID = StretchGrid(relay=0, recentre=0.0)


def _march(params, start, reuse, steps, chord=True):
    """A march whose corrector factors every step's Jacobian (DirectLU): what the reuse of its
    LU (chord iterations, refinement of the tangent) changes is then visible step by step."""
    m = Continuation(params, start, Strategy(
        SecantPredictor(), NewtonCorrector(max_iter=20, reuse_lu=reuse, chord=chord and reuse,
                                           linear=DirectLU()),
        FreeSteps(ds=DS, ds_max=DS, ds_min=0.25 * DS), GRID))
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


def test_tangent_by_refinement_or_gmres_converges_or_says_none(params, start):
    m, _ = _march(params, start, True, 2)
    A = m._arc.residual_and_jacobian(m._x)[1]
    n = tangent_by_refinement(A, m._lu)
    assert n is not None
    ref = family_tangent(m._base, m._x, m._orient)
    assert np.max(np.abs(unit_tangent(n, m.beta, m.kappa) - ref)) < 1e-9 * np.max(np.abs(ref))
    # the LU of a matrix too far from A for refinement (half its columns scaled by 0.3: the
    # refinement's error there is multiplied by 1 − 1/0.3 per step): GMRES on it gets there
    import scipy.linalg as sla
    B = A.copy()
    B[:, : A.shape[0] // 2] *= 0.3
    n3 = tangent_by_refinement(A, sla.lu_factor(B))
    assert np.max(np.abs(unit_tangent(n3, m.beta, m.kappa) - ref)) < 1e-9 * np.max(np.abs(ref))
    # the LU of an unrelated matrix: neither gets there → None, and the march solves A directly
    rng = np.random.default_rng(0)
    R = rng.standard_normal(A.shape) + np.eye(A.shape[0])
    assert tangent_by_refinement(A, sla.lu_factor(R)) is None
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
    # (measured: no LU, chord iterations on the earlier check's, against one LU)
    assert warm.stats.factorizations < cold.stats.factorizations
    assert warm.stats.lu is not None and cold.stats.lu is None
    # a warm start of another grid size changes nothing
    x0, xf0, lu = first.warm
    other, db2, dl2 = check_grid_2n(params, m.sol, n, nested=True, stages=4, max_iter=15,
                                    warm=(x0[1:], xf0, lu))
    assert other.stats.history[0] == cold.stats.history[0]
    assert (db2, dl2) == (db0, dl0)


def _held(hold=True, corrector=None, cap_shrink=1.0, cap_grow_after=6, free=None):
    """The held strategies of these tests: secant below ds = 1.2 DS, held steps up to 10 DS."""
    free = free or NewtonCorrector(max_iter=20)
    steps = (HeldSteps(ds=DS, ds_max=10 * DS, ds_min=0.1 * DS, cap_shrink=cap_shrink,
                       cap_grow_after=cap_grow_after,
                       corrector=corrector or NewtonCorrector(max_iter=20))
             if hold else FreeSteps(ds=DS, ds_max=10 * DS, ds_min=0.1 * DS))
    return Strategy(SecantPredictor(ds_max=1.2 * DS), free, steps, GRID)


class _TangentFails(Continuation):
    """A march whose tangent-predicted steps above the predictor's ds_max fail (as they do deep
    in the family, where they take ``max_iter`` iterations to do so); the length/secant steps
    below it are the real ones."""

    def _attempt(self):
        res = super()._attempt()
        if self.last_predictor == "tangent" and self.ds > self.strategy.predictor.ds_max:
            return (False, None, "failed (forced)") + res[3:]
        return res


@pytest.mark.parametrize("hold", [False, True])
def test_hold_keeps_ds_where_the_secant_works(params, start, hold):
    """``HeldSteps``: after a tangent step above the predictor's ds_max failed and a secant step
    below it passed, ds is capped there: one failure in six steps instead of one every time ds
    grows past the threshold."""
    s = _held(hold)
    m = _TangentFails(params, start, s)
    for _ in range(6):
        assert m.step() is None
    assert m.held is hold
    if hold:
        assert m.n_failed == 1 and m.ds <= s.predictor.ds_max
    else:
        assert m.n_failed >= 2


def test_chord_once_held_keeps_the_path(params, start):
    """The held corrector with ``chord`` (and an LU per step): once held, the correctors start
    with chord iterations on the last LU; ds is capped, so the march takes the same steps to the same pulses."""
    runs = {}
    for chord in (False, True):
        m = _TangentFails(params, start, _held(corrector=NewtonCorrector(
            max_iter=20, chord=chord, linear=DirectLU())))
        rows = []
        for _ in range(6):
            assert m.step() is None
            rows.append((m.ds, m.sol.x.copy(), m.sol.stats.chord_iterations))
        runs[chord] = (m, rows)
    (m0, plain), (m1, chord) = runs[False], runs[True]
    assert m0.held and m1.held
    assert [r[0] for r in plain] == [r[0] for r in chord]
    for (_, x0, _), (_, x1, _) in zip(plain, chord):
        assert x0.size == x1.size and np.max(np.abs(x1 - x0)) < 1e-10
    assert all(c == 0 for _, _, c in plain)
    assert sum(c > 0 for _, _, c in chord) >= 3       # the held steps start with chords
    assert m1.n_iterations < m0.n_iterations


SEEN = []


class _Recording(NewtonCorrector):
    """Newton that records, per attempt, its creep stop, its line search and the march's state."""

    def solve(self, problem, x0, lu=None, creep=None):
        m = BOX[0]
        SEEN.append((self.creep if creep is None else creep, self.line_search, m.held,
                     m.ds >= 0.8 * m.cap * (1 - 1e-9)))
        return super().solve(problem, x0, lu=lu, creep=creep)


BOX = [None]


def test_creep_only_once_held_and_near_the_cap(params, start):
    """The held corrector's ``creep`` stops creeping Newton after that many iterations only once
    the march is held and ds is within ``cap_shrink`` of the cap; before, and below it (after a
    halving), the free corrector's (0). Its "natural" line search acts once held, at any ds, and
    the free corrector's ("residual") before."""
    SEEN.clear()
    s = _held(corrector=_Recording(max_iter=20, creep=4, line_search="natural"),
              free=_Recording(max_iter=20), cap_shrink=0.8, cap_grow_after=3)
    m = BOX[0] = _CapFails(params, start, s)
    for _ in range(10):
        assert m.step() is None
    assert all(c == (4 if held and near else 0) for c, _, held, near in SEEN), SEEN
    assert all(ls == ("natural" if held else "residual") for _, ls, held, _ in SEEN), SEEN
    assert any(h and n for _, _, h, n in SEEN) and any(h and not n for _, _, h, n in SEEN)
    assert not SEEN[0][2] and m.held


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
    """``HeldSteps.cap_shrink``: once held, a failed attempt at the cap lowers it, so the march
    stops failing there; with a fixed cap (1.0) it fails there again and again."""
    s = _held(cap_shrink=shrink, cap_grow_after=100)
    m = _CapFails(params, start, s)
    for _ in range(10):
        assert m.step() is None
    assert m.held
    failed_held = m.n_failed - 1                 # the first failure is the tangent's (held then)
    if shrink == 1.0:
        assert m.cap == s.predictor.ds_max and failed_held >= 3
    else:
        assert failed_held == 1 and m.cap <= 0.8 * s.predictor.ds_max + 1e-15


class _CapFailsOnce(_CapFails):
    """As _CapFails, but only the first held attempt above ``limit`` fails."""

    def _attempt(self):
        if self.held and self.ds > self.limit * (1 + 1e-9) and not getattr(self, "_done", False):
            self._done = True
            return False, None, "failed (forced, held)", (math.nan, math.nan), self.q
        return Continuation._attempt(self) if self.held else _TangentFails._attempt(self)


def test_the_held_cap_grows_back_after_steps_at_it(params, start):
    """After ``cap_grow_after`` accepted steps at the lowered cap it is raised by 1/cap_shrink,
    never above the predictor's ds_max."""
    s = _held(cap_shrink=0.8, cap_grow_after=2)
    m = _CapFailsOnce(params, start, s)
    caps = []
    for _ in range(9):
        assert m.step() is None
        caps.append(m.cap)
    assert min(caps) <= 0.8 * s.predictor.ds_max + 1e-15
    assert caps[-1] == s.predictor.ds_max and max(caps) == s.predictor.ds_max


class _Got(Exception):
    pass


class _Capture(NewtonCorrector):
    """A corrector that stops the march at its ``CAPTURE[0]``-th call, keeping problem and guess."""

    def solve(self, problem, x0, lu=None, creep=None):
        CAPTURE[1] += 1
        if CAPTURE[1] == CAPTURE[0]:
            CAPTURE[2:] = [problem, np.array(x0)]
            raise _Got
        return super().solve(problem, x0, lu=lu, creep=creep)


CAPTURE = [3, 0]


@pytest.mark.slow
def test_the_held_corrector_at_9_5_km_converges_with_the_natural_line_search(tmp_path):
    """The real case behind the held corrector's natural line search: the march resumed from the
    committed 9.47 km seed (held, N = 6614) reaches the corrector of its second step,
    ds = 0.00064, which failed after 25 iterations with the ‖r‖₂ line search. With the natural
    one it converges from the same guess within 12 iterations, to a pulse near the guess (β and
    τ_d/τ_min within 1e−7). ≈ 2.5 min on two threads (the capture, then one corrector)."""
    import os
    import shutil

    from slippulse.core.params import Parameters
    from slippulse.steady.continuation import AUTO, NEWTON_TOL, FamilyRun, run_family
    from slippulse.steady.newton import newton
    seed = os.path.join(os.path.dirname(__file__), os.pardir, "steady", "seeds",
                        "seed_9473m.h5")
    out = str(tmp_path / "deep.h5")
    shutil.copy(seed, out)
    CAPTURE[:] = [3, 0]
    strategy = AUTO.replace(corrector=_Capture(max_iter=25),
                            steps=dataclasses.replace(AUTO.steps, corrector=_Capture(
                                max_iter=25, line_search="natural", creep=4, chord=True)),
                            grid=dataclasses.replace(AUTO.grid, recentre=0.0))
    with pytest.raises(_Got):
        run_family(Parameters(), out, FamilyRun(start=1.2, stop=1.008, max_length=9700,
                                                spacing=0.03, strategy=strategy))
    problem, x0 = CAPTURE[2:]
    assert problem.ds == pytest.approx(0.00064) and problem.base.n == 6614
    x, st = newton(problem, x0, tol=NEWTON_TOL, max_iter=12, line_search="natural")
    assert st.converged, st.message
    assert abs(x[-2] - x0[-2]) < 1e-7 and abs(x[-1] - x0[-1]) < 1e-7
