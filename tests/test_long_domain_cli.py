"""`slippulse steady long-domain`: a pulse re-solved on a longer domain is the same pulse (paper
Fig. S1b); bad input exits 2."""
import pytest

from slippulse.cli.app import main
from slippulse.core.h5io import read_pulse


def test_longer_domain_gives_the_same_pulse(tmp_path, capsys):
    fam = str(tmp_path / "f.h5")
    assert main(["steady", "solve", "--tau-d", "1.2", "--points", "500", "--out", fam]) == 0
    out = str(tmp_path / "long.h5")
    assert main(["steady", "long-domain", fam, "--label", "td1.2000", "--factor", "8",
                 "--out", out]) == 0
    short, long = read_pulse(fam)[0], read_pulse(out)[0]
    assert long.converged and long.extra["domain_factor"] == 8.0
    assert long.xi[-1] - long.xi[0] > 7.0 * (short.xi[-1] - short.xi[0])
    assert long.L == pytest.approx(short.L, rel=1e-3)
    assert long.beta == pytest.approx(short.beta, rel=1e-3)
    capsys.readouterr()
    for argv, word in ((["--label", "td9.9"], "--label"), (["--factor", "0.5"], "--factor")):
        assert main(["steady", "long-domain", fam, *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and word in err[0]


def test_one_side_extension_keeps_the_grid_and_the_pulse(tmp_path):
    """--side ahead / behind: the pulse's own nodes are kept, that side's distance from the
    leading edge doubles, the other end stays, and the pulse (β, L) does not move."""
    import numpy as np

    from slippulse.steady.solver import extended_grid
    fam = str(tmp_path / "f.h5")
    assert main(["steady", "solve", "--tau-d", "1.2", "--points", "500", "--out", fam]) == 0
    short = read_pulse(fam)[0]
    lead = short.xi[np.argmax(short.v)]
    for side in ("ahead", "behind"):
        out = str(tmp_path / f"{side}.h5")
        assert main(["steady", "long-domain", fam, "--label", "td1.2000", "--side", side,
                     "--factor", "2", "--out", out]) == 0
        long = read_pulse(out)[0]
        assert long.converged and long.extra["domain_side"] == side
        assert np.isin(short.xi, long.xi).all() and long.n_points > short.n_points
        front, back = long.xi[-1] - lead, lead - long.xi[0]
        if side == "ahead":
            assert front == pytest.approx(2 * (short.xi[-1] - lead), rel=1e-12)
            assert long.xi[0] == short.xi[0]
        else:
            assert back == pytest.approx(2 * (lead - short.xi[0]), rel=1e-12)
            assert long.xi[-1] == short.xi[-1]
        assert long.L == pytest.approx(short.L, rel=1e-4)
        assert long.beta == pytest.approx(short.beta, rel=1e-4)
    # the new cells grow at the end cells' ratio, and a factor below 1 is refused
    xi = np.cumsum(1.1 ** np.arange(20.0))
    ext = extended_grid(xi, xi[5], ahead=3.0)
    assert np.all(np.diff(ext) > 0) and ext[-1] == pytest.approx(xi[5] + 3 * (xi[-1] - xi[5]))
    with pytest.raises(ValueError, match="behind"):
        extended_grid(xi, xi[5], behind=0.5)


def test_a_re_solve_on_the_normal_line_is_the_fixed_tau_d_one(tmp_path):
    """``resolve_on_normal_line`` (the fallback of ``--side`` where fixed-τ_d Newton creeps, near
    β → 1): on the 1.2 pulse's grid extended ahead it converges to the pulse the fixed-τ_d re-solve
    gives, τ_d moving along the family's normal line by a hair, β and L with it."""
    import numpy as np

    from slippulse.steady.bifurcation import pulse_system
    from slippulse.steady.continuation.gridcheck import resolve_on_normal_line
    from slippulse.steady.newton import SolveStats
    from slippulse.steady.solver import SteadySolution, resolve_on_extended_domain
    fam = str(tmp_path / "f.h5")
    assert main(["steady", "solve", "--tau-d", "1.2", "--points", "500", "--out", fam]) == 0
    pulse, params = read_pulse(fam)
    fixed = resolve_on_extended_domain(params, pulse, ahead=2.0)
    assert fixed.stats.converged
    prob, x, _ = pulse_system(pulse, params)
    sol = SteadySolution(prob, x, SolveStats(True, "stored", 0, 0.0), 0.0, 0)
    normal = resolve_on_normal_line(params, sol, fixed.xi)
    assert normal.stats.converged and np.array_equal(normal.xi, fixed.xi)
    a, b = fixed.to_pulse(), normal.to_pulse()
    assert abs(b.tau_d_ratio - a.tau_d_ratio) < 1e-6
    assert b.beta == pytest.approx(a.beta, rel=1e-5) and b.L == pytest.approx(a.L, rel=1e-5)
