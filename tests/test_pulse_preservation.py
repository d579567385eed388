"""Short-time evolution of a seeded steady pulse preserves it (docs/dynamic.md §3).

Cheap case: τ_d = 1.05 τ_min (β = 0.47, L = 7.3 m), steady pulse from a coarse family (N = 1000,
continuation 1.2 → 1.05 in steps of 0.025, ~2 s), SBI grid Δx = 4 mm, 2 L ahead + 2 L behind
(N = 7288), adaptive steps, far field added, frame following; 0.5 L travelled (3879 steps, ~11 s).

Tolerance, from a convergence check of this case at 0.5 L (`slippulse dynamic verify`,
errors c_p / v_max / L / ln v):

    steady N = 1000, Δx = 4 mm, 2 L + 2 L   6.2e-4  7.8e-4  6.5e-4  4.1e-4    (this test)
    steady N = 1000, Δx = 4 mm, 3 L + 3 L   5.7e-4  5.6e-4  7.1e-4  4.3e-4    (domain)
    steady N = 1000, Δx = 2 mm, 2 L + 2 L   6.5e-4  7.6e-4  7.2e-4  4.3e-4    (SBI grid)
    steady N = 3000, Δx = 4 mm, 2 L + 2 L   8.9e-5  3.6e-4  2.9e-5  2.1e-4    (steady grid)

The error is dominated by the steady solution's resolution (N = 1000 → 3000 divides the c_p and L
errors by 7 and 20), not by the SBI grid or the domain (changes ≤ 2.2e-4). The tolerance 2e-3 is
2.6× the largest measured error and 9× the largest change under refinement: a
regression that doubles the error still passes only if it stays below the level the coarse steady
grid itself produces; seeding mistakes fail it by far: a history started at t = 0 gives
v_max and c_p errors of 0.59 and 0.54 within 0.025 L; no far-field load on this short domain gives
L error 8.6e-2 and ln v error 5.5e-2 at 0.5 L (both tested below).

At 1.2 τ_min the same machinery shows an exponentially growing deviation (e-folding every
0.045 L, independent of Δx, Δt, domain and SOE kernel: an unstable mode of the pulse, see
BENCHMARKS.md ("Seeded steady pulses")), so 1.2 τ_min cannot be "preserved" over 0.5 L; the slow test
``test_unstable_mode_growth_rate_is_converged`` checks that growth rate.
"""
import numpy as np
import pytest

from slippulse.timedomain.verify import VerifySettings, verify_pulse
from slippulse.timedomain.seeding import DomainSpec
from slippulse.dynamics.stepper import TimeStepRule

TOL = 2e-3


@pytest.fixture(scope="module")
def pulse105(params, tmp_path_factory):
    from slippulse.steady.continuation import FamilyRun, run_family
    from slippulse.core.h5io import read_pulse
    path = str(tmp_path_factory.mktemp("fam") / "fam.h5")
    run_family(params, path, FamilyRun(start=1.2, stop=1.05, step=0.025, n_points=1000))
    return read_pulse(path, "td1.0500")[0]


def test_pulse_preserved_over_half_a_length(pulse105, params):
    res = verify_pulse(pulse105, params, 0.5, DomainSpec(dx=4e-3, ahead=2.0, behind=2.0),
                       VerifySettings(n_samples=10), progress=False)
    assert res.info["status"] == "finished"
    assert res.info["travelled"] >= 0.5 * (1 - 1e-3)
    for key in ("c_p_error", "v_max_error", "L_error", "lnv_error"):
        assert abs(res.errors[key]) < TOL, (key, res.errors[key])
    # the whole time series stays inside the tolerance, not only the end
    for key in ("v_max_error", "L_error", "lnv_error"):
        assert np.nanmax(np.abs(res.series[key])) < TOL, key


def test_history_started_at_rest_breaks_the_pulse(pulse105, params):
    """Same slip and state, but no elastodynamic past: a start-up transient radiates and the
    pulse is off by far more than the tolerance within 0.05 L (measured: 0.59 in v_max)."""
    res = verify_pulse(pulse105, params, 0.05, DomainSpec(dx=4e-3, ahead=2.0, behind=2.0),
                       VerifySettings(n_samples=5, history_start="rest"), progress=False)
    # the run itself must succeed (a crash or a lost pulse is not the failure this test expects):
    # measured status 'finished', v_max error 0.59 at the first sample
    assert res.info["status"] == "finished"
    worst = max(np.nanmax(np.abs(res.series[k])) for k in ("v_max_error", "lnv_error"))
    assert worst > 10 * TOL


@pytest.mark.slow
def test_unstable_mode_growth_rate_is_converged(params):
    """τ_d = 1.2 τ_min: |v_max − v_max⁰| grows like e^{γ d} (d in pulse lengths) with the same γ
    for Δt halved (ξ_s = 0.25) although the seed changes sign — a property of the pulse, not of the
    time step. Measured γ = 22.2 and 22.9 per L (fit where 3e-4 ≤ |error| ≤ 3e-2); 22.9 at Δx = 1 mm.
    ~60 s."""
    from slippulse.steady.solver import solve_pulse
    pulse = solve_pulse(params, 1.2, n_points=3000).to_pulse()
    rates = []
    for xi_stab in (0.5, 0.25):
        run = VerifySettings(n_samples=17, rule=TimeStepRule(kind="adaptive", xi_stab=xi_stab))
        res = verify_pulse(pulse, params, 0.42, DomainSpec(dx=2e-3), run, progress=False)
        rates.append(res.info["growth_rate_v_max"])
    assert all(18 < g < 28 for g in rates), rates
    assert abs(rates[0] - rates[1]) < 0.1 * rates[0], rates


@pytest.mark.slow
def test_without_far_field_the_short_domain_distorts_the_pulse(pulse105, params):
    """The bare period (λ = 4 L) is a train of pulses: their images distort the pulse
    (measured L error 8.6e-2 at 0.5 L), so the far-field load is what makes the short domain work."""
    res = verify_pulse(pulse105, params, 0.5, DomainSpec(dx=4e-3, ahead=2.0, behind=2.0),
                       VerifySettings(n_samples=10, far_field="none"), progress=False)
    assert abs(res.errors["L_error"]) > 10 * TOL
