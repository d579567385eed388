"""Continuation of the family on a short coarse range, and resume after interruption."""
import numpy as np
import pytest

from slippulse.continuation import run_family
from slippulse.h5io import list_pulses, read_pulse
from slippulse.params import ParameterError


def test_short_family_and_resume(params, tmp_path):
    out = str(tmp_path / "fam.h5")
    rep = run_family(params, out, start=1.2, stop=1.19, step=0.005, n_points=500)
    assert rep.written == ["td1.2000", "td1.1950", "td1.1900"] and not rep.stopped_early
    pulses = [read_pulse(out, lab)[0] for lab in list_pulses(out)]
    assert all(p.converged and p.max_residual <= 1e-13 for p in pulses)
    beta = [p.beta for p in pulses]
    assert np.all(np.diff(beta) > 0)                # pulses speed up as τ_d decreases
    # "interrupted" run: extend the range; the existing pulses are not recomputed
    before = {lab: read_pulse(out, lab)[0].wall_time for lab in list_pulses(out)}
    rep2 = run_family(params, out, start=1.2, stop=1.18, step=0.005, n_points=500)
    assert rep2.resumed_from == "td1.1900"
    assert rep2.written == ["td1.1850", "td1.1800"]
    after = {lab: read_pulse(out, lab)[0].wall_time for lab in before}
    assert after == before
    # continuation and a direct solve from the neighbour agree on the same grid size
    assert read_pulse(out, "td1.1800")[0].beta == pytest.approx(0.012002, rel=1e-3)


def test_family_refuses_bad_ranges(params, tmp_path):
    with pytest.raises(ParameterError, match="to="):
        run_family(params, str(tmp_path / "f.h5"), start=1.1, stop=1.2)
    with pytest.raises(ParameterError, match="tau_d/tau_min"):
        run_family(params, str(tmp_path / "f.h5"), start=1.2, stop=0.99)
    with pytest.raises(ParameterError, match="step"):
        run_family(params, str(tmp_path / "f.h5"), start=1.2, stop=1.1, step=-0.01)


def test_beta_mode_inverts_tau_d_mode(params):
    """Fixing β at the speed found at τ_d = 1.2 τ_min and solving for τ_d gives back 1.2."""
    from slippulse.continuation import solve_at_beta
    from slippulse.solver import solve_pulse
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
        run_family(params, out, start=1.2, stop=1.185, step=0.005, n_points=500,
                   progress=interrupt_after_two)
    # the pulse whose progress call was interrupted had not been written yet
    assert list_pulses(out) == ["td1.2000"]
    rep = run_family(params, out, start=1.2, stop=1.185, step=0.005, n_points=500)
    assert rep.resumed_from == "td1.2000"
    assert list_pulses(out) == ["td1.2000", "td1.1950", "td1.1900", "td1.1850"]
    assert all(read_pulse(out, lab)[0].converged for lab in list_pulses(out))
