"""Friction-law identities and derived scales (closed-form checks)."""
import math

import numpy as np
import pytest

from slippulse.core import friction as fr
from slippulse.core.params import ParameterError, Parameters


def test_state_steady_state_is_root_of_g(params):
    v = np.geomspace(1e-12, 10.0, 200)
    phi = fr.phi_ss(v, params.v_star, params.D)
    assert np.max(np.abs(fr.g(v, phi, params.v_star, params.D))) < 1e-14


@pytest.mark.parametrize("v,phi", [(1e-9, 3.0), (2e-7, 1.0), (6e-3, 1e-4), (3.0, 1e-7)])
def test_partial_derivatives_match_finite_differences(params, v, phi):
    a = params.law_args
    h = 1e-4
    dfdv = (fr.f(v * (1 + h), phi, *a) - fr.f(v * (1 - h), phi, *a)) / (2 * h * v)
    dfdp = (fr.f(v, phi * (1 + h), *a) - fr.f(v, phi * (1 - h), *a)) / (2 * h * phi)
    dgdv = (fr.g(v * (1 + h), phi, params.v_star, params.D)
            - fr.g(v * (1 - h), phi, params.v_star, params.D)) / (2 * h * v)
    assert fr.df_dv(v, phi, *a) == pytest.approx(dfdv, rel=1e-6)
    assert fr.df_dphi(v, phi, *a) == pytest.approx(dfdp, rel=1e-6)
    assert fr.dg_dv(v, phi, params.v_star, params.D) == pytest.approx(dgdv, rel=1e-6)


def test_extrema_of_steady_friction_curve(params):
    # stationary points: derivative vanishes, and they are a local max then a min
    for v in (params.v_peak, params.v_min):
        slope = fr.df_ss_dlnv(v, *params.law_args)
        assert abs(slope) < 1e-12
    for v, sign in ((params.v_peak, -1), (params.v_min, +1)):
        around = params.tau_ss(np.array([v * 0.99, v * 1.01])) - params.tau_ss(v)
        assert np.all(sign * around > 0)
    # sanity values of physics.md
    assert params.tau_min == pytest.approx(0.34067e6, rel=2e-5)
    assert params.v_min == pytest.approx(5.97e-3, rel=2e-3)
    assert params.tau_peak == pytest.approx(0.454e6, rel=2e-3)
    assert params.v_peak == pytest.approx(0.55e-6, rel=2e-2)
    assert params.L0 == pytest.approx(0.884, rel=1e-3)
    assert params.L_Gc == pytest.approx(0.0504, rel=1e-3)


def test_v_stick_and_v_ss_are_roots(params):
    tau_d = 1.2 * params.tau_min
    vs, vss = params.v_stick(tau_d), params.v_ss(tau_d)
    assert vs == pytest.approx(1.65e-7, rel=2e-3)
    assert vs < params.v_peak < params.v_min < vss
    for v in (vs, vss):
        assert abs(params.tau_ss(v) / tau_d - 1.0) < 4e-16 * 8
    assert params.phi_rest(tau_d) == pytest.approx(params.D / math.hypot(vs, params.v_star), rel=1e-15)


def test_exact_state_step(params):
    w, dt, phi0 = 3.0, 0.7, 2.0
    exact = 1 / w + (phi0 - 1 / w) * math.exp(-w * dt)
    assert fr.state_step(phi0, w, dt) == pytest.approx(exact, rel=1e-15)
    assert fr.state_step(phi0, 1e9, 1.0) == pytest.approx(1e-9, rel=1e-12)   # stiff limit


@pytest.mark.parametrize("bad", [{"mu": -1.0}, {"sigma": 0.0}, {"D": float("nan")},
                                 {"c_s": float("inf")}, {"alpha": 1.0}])
def test_bad_parameters_are_refused_with_their_name(bad):
    with pytest.raises(ParameterError) as exc:
        Parameters(**bad)
    assert list(bad)[0] in str(exc.value)


@pytest.mark.parametrize("ratio", [0.9, 1.0, 1.3319, 1.5])
def test_tau_d_outside_the_pulse_range_is_refused(params, ratio):
    with pytest.raises(ParameterError, match="tau_d/tau_min"):
        params.v_stick(ratio * params.tau_min)
