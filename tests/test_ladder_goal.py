"""The spectrum's ladder climbs to an accuracy goal, and its level 0 is clipped (its
cost: docs/spectrum.md §4). Newton judges the pair it returns."""

import numpy as np
import pytest

from slippulse.spectrum.refine import goal, level0_size


def test_goal_is_absolute_or_relative_whichever_is_larger():
    assert goal(1e-4, 1e-3, 0.0178) == pytest.approx(1e-4)       # 1.02 tau_min
    assert goal(1e-4, 1e-3, 0.6654) == pytest.approx(6.654e-4)   # 1.05 tau_min
    assert goal(1e-4, 1e-3, -0.6654) == pytest.approx(6.654e-4)
    assert goal(1e-4, 0.0, 22.65) == pytest.approx(1e-4)


def test_level0_is_the_pulse_N_clipped_unless_given():
    assert level0_size(700, 1000, None, 2828) == 1000
    assert level0_size(1250, 1000, None, 2828) == 1250
    assert level0_size(3542, 1000, None, 2828) == 2828
    assert level0_size(3542, 1000, None, None) == 3542
    assert level0_size(3542, 1000, 2000, 2828) == 2000          # --points overrides both


@pytest.fixture(scope="module")
def ladder12(pulse12, params):
    """Level 0 of the 1.2 tau_min pulse on its map at N = 400, with its leading eigenvalue."""
    from slippulse.spectrum.refine import mapped_pulse
    from slippulse.spectrum.pulse import pulse_spectrum
    from slippulse.steady.grid import GridMap
    p = pulse12.to_pulse()
    gmap = GridMap(p.xi)
    p0 = mapped_pulse(params, p, gmap, 400).to_pulse()
    first = pulse_spectrum(p0, params, guesses=[22.65 * p0.c_p / p0.L], extra=False,
                           pin_translation=True, neutral=False)
    assert first.status == "converged" and np.isnan(first.neutral).all()
    return p0, gmap, first


def test_ladder_stops_at_the_goal_and_says_when_its_cap_stops_it(ladder12, params):
    from slippulse.spectrum.refine import Ladder, refine_leading
    p0, gmap, first = ladder12
    kw = dict(levels=1, pin_translation=True, max_points=800)
    easy = refine_leading(p0, params, first, gmap, Ladder(target=1.0, **kw))
    assert easy.status == "converged" and easy.n_points == [400, 566] and easy.target_met
    # unreachable: climbs to the cap (800) and says so
    hard = refine_leading(p0, params, first, gmap, Ladder(target=1e-12, **kw))
    assert hard.n_points == [400, 566, 800] and not hard.target_met
    assert "not reached" in hard.message
    # the relative part of the goal: half of s L/c_p ≈ 11 is met by two levels
    rel = refine_leading(p0, params, first, gmap, Ladder(target=1e-12, rel_target=0.5, **kw))
    assert rel.n_points == [400, 566] and rel.target_met
    assert rel.target == pytest.approx(0.5 * rel.per_length()[0])
    # pinned: the translation eigenvalue is computed on level 0 only
    assert np.isnan(hard.translation_levels[1:]).all()


def test_newton_reports_the_true_residual_of_the_pair_it_returns(ladder12, params):
    """A converged step is judged by the residual of the new pair, linearised about the last
    σ with the matrices in hand; it must be the true backward error of the pair returned."""
    from scipy.interpolate import CubicSpline

    from slippulse.spectrum.eigensolve import relres, newton_eigen
    from slippulse.spectrum.refine import mapped_pulse
    from slippulse.spectrum.pulse import StabilityOperator
    p0, gmap, first = ladder12
    q = mapped_pulse(params, p0, gmap, 566).to_pulse()
    V = first.modes[0]["V"]
    x0 = CubicSpline(p0.xi, V.real)(q.xi) + 1j * CubicSpline(p0.xi, V.imag)(q.xi)
    op = StabilityOperator(q, params, pin_translation=True)
    guess = first.leading * (q.c_p / q.L) / (p0.c_p / p0.L)
    e = newton_eigen(op, guess, x0, tol=1e-6)
    assert e.converged, e.message
    true = relres(op.matrices(e.sigma, deriv=False)[0], e.V)
    assert true < 1e-6
    assert abs(e.residual - true) < 1e-9 + 1e-3 * true, (e.residual, true)


@pytest.mark.parametrize("args, name", [(["--max-points", "500"], "max-points"),
                                        (["--rel-target", "-1"], "rel-target"),
                                        (["--rel-target", "1.5"], "rel-target")])
def test_cli_ladder_options_out_of_range_are_one_line(tmp_path, pulse12, params, args, name):
    from slippulse.core.h5io import write_pulse
    f = str(tmp_path / "one.h5")
    write_pulse(f, pulse12.to_pulse(), params)
    import cli_inproc
    r = cli_inproc.run(["steady", "stability", f, "-q", *args])
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().count("\n") == 0 and name in r.stderr, r.stderr


def test_level0_falls_back_to_the_pulse_own_N_when_the_clip_fails(tmp_path, pulse12, params,
                                                                    monkeypatch):
    """Deep pulses beyond L ≈ 2.5 km do not re-solve on N = 2828 (the default clip) but do on
    their own N = 3542. Here the re-solve is made to fail below the pulse's own N (700): level 0
    then uses N = 700, and says nothing failed; where the own N fails too, the message names both."""
    from slippulse.core.h5io import write_pulse
    from slippulse.spectrum import family as sf
    path = str(tmp_path / "td12.h5")
    write_pulse(path, pulse12.to_pulse(), params)
    tried = []
    real = sf.solve_level0

    creeps = []

    def level0(pulse, prm, gmap, n0, creep=0):
        tried.append(n0)
        creeps.append(creep)
        if n0 < 700:
            return pulse, f"steady re-solve on the mapped grid (N = {n0}) did not converge: mock"
        return real(pulse, prm, gmap, n0, creep)

    monkeypatch.setattr(sf, "solve_level0", level0)
    rep = sf.run_spectrum(path, sf.SpectrumSettings(extra=False, levels=0, min_points=0, max_points=500))
    assert tried == [500, 700]
    # the clipped attempt, which has the own N to fall back on, gives up when it creeps; the
    # own N, the last resort, does not
    assert creeps == [sf.LEVEL0_CREEP, 0] and sf.LEVEL0_CREEP > 0
    res = rep.results[0]
    assert res.status == "converged" and res.n_points == 700 and not rep.failed
    assert res.leading.real / res.rate_unit == pytest.approx(22.65, rel=0.02)

    def never(pulse, prm, gmap, n0, creep=0):
        tried.append(n0)
        return pulse, f"steady re-solve on the mapped grid (N = {n0}) did not converge: mock"

    monkeypatch.setattr(sf, "solve_level0", never)
    tried.clear()
    rep = sf.run_spectrum(path, sf.SpectrumSettings(extra=False, levels=0, min_points=0, max_points=500), overwrite=True)
    assert tried == [500, 700] and rep.failed == ["td1.2000"]
    assert "level 0 on the clipped N = 500" in rep.results[0].message
    assert "level 0 on the pulse's own N = 700: " in rep.results[0].message
    # --points (an explicit level 0) is not overridden
    tried.clear()
    sf.run_spectrum(path, sf.SpectrumSettings(extra=False, levels=0, level0_points=500), overwrite=True)
    assert tried == [500]


def test_creep_reaches_the_newton_of_a_mapped_resolve(pulse12, params, monkeypatch):
    """mapped_pulse(creep=k) → resolve_on_grid → solve_on_grid → newton(creep=k); the other
    solvers, which have no creep stop, are not given it."""
    from slippulse.spectrum.refine import mapped_pulse
    from slippulse.steady import newton as nw
    from slippulse.steady.grid import GridMap
    seen = []
    real = nw.SOLVERS["newton"]

    def spy(problem, x0, **kw):
        seen.append(kw.get("creep"))
        return real(problem, x0, **kw)

    monkeypatch.setitem(nw.SOLVERS, "newton", spy)
    p = pulse12.to_pulse()
    gmap = GridMap(p.xi)
    sol = mapped_pulse(params, p, gmap, p.n_points, creep=4)
    assert sol.stats.converged and seen == [4]
    mapped_pulse(params, p, gmap, p.n_points)
    assert seen == [4, None]


def test_a_clipped_level0_climbs_a_third_level_and_a_short_stored_ladder_is_redone(
        tmp_path, pulse12, params):
    """A level 0 below the pulse's own N (here 400 < 700) is not trusted on two levels: it
    climbs CLIPPED_LEVELS levels, so that its estimate observes an order (at 6.30 km the
    clipped two-level ladder was 2.1 times its summed bars off). A level 0 at or above the own N
    keeps the levels asked for; a two-level clipped ladder stored before the rule is redone."""
    import h5py

    from slippulse.core.h5io import write_pulse
    from slippulse.spectrum import family as sf
    assert sf.CLIPPED_LEVELS == 2
    assert sf.clipped_levels(1, 2828, 3542) == 2 and sf.clipped_levels(1, 3542, 3542) == 1
    assert sf.clipped_levels(3, 2828, 3542) == 3 and sf.clipped_levels(0, 2828, 3542) == 0
    assert sf.clipped_levels(1, 6000, 9000) == 1            # 12000 > MAX_LADDER_POINTS
    path = str(tmp_path / "td12.h5")
    write_pulse(path, pulse12.to_pulse(), params)
    kw = dict(extra=False, levels=1, min_points=0, target=None)
    rep = sf.run_spectrum(path, sf.SpectrumSettings(max_points=400, **kw))
    assert rep.results[0].refined.n_points == [400, 566, 800], rep.results[0].refined.message
    # the same pulse at its own N: one level above, as asked
    own = sf.run_spectrum(path, sf.SpectrumSettings(max_points=None, **kw), overwrite=True)
    assert own.results[0].refined.n_points == [700, 990]
    # a clipped two-level ladder in the file (as written before the rule) is not kept
    sf.run_spectrum(path, sf.SpectrumSettings(max_points=400, **kw), overwrite=True)
    with h5py.File(path, "r+") as h5:
        g = h5["pulses/td1.2000/spectrum"]
        g.attrs["refine_n_points"] = np.array([400, 566])
    again = sf.run_spectrum(path, sf.SpectrumSettings(max_points=400, **kw))
    assert again.skipped == [] and again.results[0].refined.n_points == [400, 566, 800]
    kept = sf.run_spectrum(path, sf.SpectrumSettings(max_points=400, **kw))
    assert kept.skipped == ["td1.2000"] and kept.results == []
