"""``steady solve --tau-d X`` converges over its advertised range
(reach.SOLVE_RANGE) by continuation from the built-in guess at 1.2, and each pulse agrees with the
family's pulse at that τ_d within the family's grid tolerance (β 1e-5, L 1e-4 relative).

Reference below 1.2: the family 1.2 → X (``run_family``, its default N and step). Above 1.2 the
family goes down only, so the reference is the family started at X itself (its first pulse comes
from the built-in guess there, which converges at 1.22, 1.25 and 1.3, not at 1.205)."""
import pytest

from slippulse.core import h5io
from slippulse.core.params import DEFAULT as P
from slippulse.steady.continuation import FamilyRun, run_family
from slippulse.steady.reach import SOLVE_RANGE, reach_pulse

BETA_TOL, L_TOL = 1e-5, 1e-4


def _family_pulse(tmp_path, x):
    out = str(tmp_path / f"fam{x}.h5")
    if x < 1.2:
        rep = run_family(P, out, FamilyRun(start=1.2, stop=x, step=0.005))
    else:
        rep = run_family(P, out, FamilyRun(start=x, stop=x - 0.005, step=0.005))
    assert not rep.stopped_early, rep.stop_reason
    return h5io.read_pulse(out, h5io.pulse_label(x))[0]


def _check(tmp_path, x, n_points=2000):
    sol, route = reach_pulse(P, x, n_points=n_points)
    assert sol is not None and sol.stats.converged, route
    got = sol.to_pulse()
    assert got.extra["n_humps"] == 1
    ref = _family_pulse(tmp_path, x)
    print(f"reach {x}: beta {got.beta:.8f} vs family {ref.beta:.8f} (diff {got.beta - ref.beta:.1e}), "
          f"L {got.L:.6g} vs {ref.L:.6g} (rel {got.L / ref.L - 1:.1e}); {route}")
    assert abs(got.beta - ref.beta) <= BETA_TOL, (x, got.beta, ref.beta)
    assert abs(got.L / ref.L - 1) <= L_TOL, (x, got.L, ref.L)
    return got


def test_reach_near_the_guess(tmp_path):
    """Default suite: one family step down from 1.2 (seconds)."""
    _check(tmp_path, 1.195, n_points=1250)


@pytest.mark.slow
@pytest.mark.parametrize("x", [1.3, 1.25, 1.22, 1.19, 1.15, 1.1, 1.05, 1.02])
def test_reach_over_the_range(tmp_path, x):
    _check(tmp_path, x)


@pytest.mark.slow
def test_reach_at_the_top_of_the_range():
    """1.32, the top of SOLVE_RANGE: the family cannot start there from the built-in guess, so the
    reference is the reached pulse re-solved on a grid 1.5 times finer, adapted to it."""
    import numpy as np
    from slippulse.steady.solver import solve_pulse
    x = SOLVE_RANGE[1]
    sol, route = reach_pulse(P, x, n_points=2000)
    assert sol is not None and sol.stats.converged, route
    got = sol.to_pulse()
    assert got.extra["n_humps"] == 1 and 0 < got.beta < 1e-3
    fine = solve_pulse(P, x, n_points=3000, guess=(got.xi, np.log(got.v), got.beta), passes=0)
    assert fine.stats.converged, fine.stats.message
    ref = fine.to_pulse()
    assert abs(got.beta / ref.beta - 1) <= 1e-3, (got.beta, ref.beta)
    assert abs(got.L / ref.L - 1) <= L_TOL, (got.L, ref.L)


def test_range_is_advertised_and_enforced(capsys):
    from slippulse.cli.app import build_parser, main
    assert SOLVE_RANGE == (1.015, 1.32)
    helptext = build_parser()._subparsers._group_actions[0].choices["steady"]
    assert helptext is not None
    for x in ("1.01", "1.325", "1.33"):
        assert main(["steady", "solve", "--tau-d", x]) == 2
        assert f"tau-d={x}" in capsys.readouterr().err


def test_a_final_solve_that_cannot_start_is_a_failure_with_its_reason(monkeypatch):
    """The walk up reaches the target, but the final solve on N points raises (at 1.325 τ_min
    with the default N the grid could not be laid: "cannot measure the pulse length"): reach_pulse
    returns no solution and says why, instead of a traceback."""
    import slippulse.steady.reach as reach
    real = reach.solve_pulse

    def failing_final(*args, **kw):
        if kw.get("passes") == 0 and "max_iter" not in kw:      # the final solve, not the walk's
            raise RuntimeError("cannot measure the pulse length on this solution")
        return real(*args, **kw)

    monkeypatch.setattr(reach, "solve_pulse", failing_final)
    sol, why = reach.reach_pulse(P, 1.205, n_points=500)
    assert sol is None
    assert "cannot measure the pulse length" in why and "continued up from 1.2" in why
