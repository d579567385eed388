"""State integration, Jacobian and full solves of the steady pulse problem."""
import math
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

from slippulse.core import friction as fr
from slippulse.core.h5io import SchemaError, read_pulse, write_pulse
from slippulse.steady.hilbert import hilbert_matrix
from slippulse.core.params import ParameterError
from slippulse.steady.solver import default_guess, solve_pulse
from slippulse.steady.equations import (RADAU_A, RADAU_C, SteadyProblem, integrate_state,
                                        integrate_state_radau)


def manufactured_state(params, n, beta_cs=20.0):
    """Prescribe φ(t) = φ_r e^{−κt} + φ_∞ and derive v from g: w = (1 − φ')/φ, v = √((wD)² − v*²).

    A material point at ξ has been travelling for t = (ξ_N − ξ)/(β c_s) since ξ_N."""
    phi_r, phi_inf, kappa = 2.5, 1e-3, 2e3
    xi = np.concatenate([np.linspace(-0.2, 0.0, n // 2, endpoint=False), np.linspace(0.0, 0.05, n - n // 2)])
    t = (xi[-1] - xi) / beta_cs
    phi = phi_r * np.exp(-kappa * t) + phi_inf
    w = (1.0 + kappa * phi_r * np.exp(-kappa * t)) / phi
    v = np.sqrt((w * params.D) ** 2 - params.v_star ** 2)
    return xi, v, phi, w, beta_cs


def test_state_integration_second_order_against_exact_solution(params):
    errs = []
    for n in (200, 400, 800):
        xi, v, phi_ex, w, c = manufactured_state(params, n)
        dw = v * v / (params.D ** 2 * w)
        phi = integrate_state(xi, v, c, phi_ex[-1], w, dw)[0]
        errs.append(np.max(np.abs(phi / phi_ex - 1.0)))
    assert errs[-1] < 1e-3
    assert np.log2(errs[1] / errs[2]) > 1.9, errs


def radau_state(params, xi, v, beta_cs, phi_end):
    return integrate_state_radau(np.asarray(xi, float), np.log(np.asarray(v, float)), beta_cs,
                                 phi_end, params.v_star, params.D, RADAU_A, RADAU_C)


def test_state_integration_fourth_order_against_exact_solution(params):
    errs = []
    for n in (200, 400, 800):
        xi, v, phi_ex, w, c = manufactured_state(params, n)
        phi = radau_state(params, xi, v, c, phi_ex[-1])[0]
        errs.append(np.max(np.abs(phi / phi_ex - 1.0)))
    assert errs[-1] < 1e-8
    assert np.log2(errs[0] / errs[1]) > 3.7 and np.log2(errs[1] / errs[2]) > 3.7, errs


@pytest.mark.parametrize("order", [2, 4])
def test_state_integration_exact_at_constant_slip_rate(params, order):
    # constant v on a random non-uniform grid, rest state off φ_ss: φ relaxes as e^{−w t} exactly
    rng = np.random.default_rng(1)
    xi = np.sort(rng.uniform(-1.0, 1.0, 50))
    v = np.full(xi.size, 3e-3)
    w = fr.heal_rate(v, params.v_star, params.D)
    c, phi_end = 5.0, 5e-4
    exact = 1.0 / w + (phi_end - 1.0 / w) * np.exp(-w * (xi[-1] - xi) / c)
    if order == 2:
        phi = integrate_state(xi, v, c, phi_end, w, v * v / (params.D ** 2 * w))[0]
    else:
        phi = radau_state(params, xi, v, c, phi_end)[0]
    assert np.max(np.abs(phi / exact - 1.0)) < 1e-13


def test_state_integration_radau_is_stiff_accurate(params):
    """v falls by 8 decades over five cells (an under-resolved leading edge): as w h → ∞ (β c_s → 0)
    φ_i → 1/w_i at every node, the deviation falling ∝ 1/(w h); φ stays positive."""
    xi = np.linspace(0.0, 1.0, 6)
    v = np.array([1e-1, 1e-1, 1e-2, 1e-5, 1e-9, 1e-9])
    w = fr.heal_rate(v, params.v_star, params.D)
    phi_end = float(fr.phi_ss(1e-9, params.v_star, params.D))
    dev = []
    for c in (1e-4, 1e-6, 1e-8):
        phi = radau_state(params, xi, v, c, phi_end)[0]
        assert np.all(phi > 0.0)
        dev.append(np.max(np.abs(phi * w - 1.0)))
    assert dev[2] < 1e-6
    assert dev[0] / dev[1] > 50 and dev[1] / dev[2] > 50, dev
    # the cell of constant v next to node 0 lands on φ_ss exactly in the limit
    phi = radau_state(params, [0.0, 1.0, 2.0], [1e-1, 1e-1, 1e-7], 1e-9, 3.0)[0]
    assert phi[0] == pytest.approx(fr.phi_ss(1e-1, params.v_star, params.D), rel=1e-12)


def test_state_integration_is_stiff_accurate(params):
    # v jumps by 6 orders of magnitude across one long cell: φ must land on φ_ss(v), not overshoot
    xi = np.array([0.0, 1.0, 2.0])
    v = np.array([1e-1, 1e-1, 1e-7])
    w = fr.heal_rate(v, params.v_star, params.D)
    phi = integrate_state(xi, v, 1e-3, 3.0, w, v * v / (params.D ** 2 * w))[0]
    assert phi[0] == pytest.approx(fr.phi_ss(1e-1, params.v_star, params.D), rel=1e-12)


@pytest.mark.parametrize("order", [2, 4])
@pytest.mark.parametrize("free", ["beta", "tau_d", "both"])
def test_jacobian_matches_finite_differences(params, free, order):
    xi, y, beta = default_guess(params, 1.2, 120)
    k = int(np.argmin(np.abs(xi)))
    prob = SteadyProblem(params, 1.2, xi, k, float(y[k]), free=free, beta=beta, state_order=order)
    x = np.concatenate([y, {"beta": [beta], "tau_d": [1.2], "both": [beta, 1.2]}[free]])
    r, J = prob.residual_and_jacobian(x)
    assert np.allclose(r, prob.residual(x), rtol=0, atol=1e-14)
    Jfd = np.empty_like(J)
    for j in range(x.size):
        # fourth-order central difference (the order-4 state makes ∂Δ/∂y curved enough that the
        # second-order one is off by 2e-7 of max|J| at this step)
        h = 1e-6 * max(1.0, abs(x[j]))
        e = np.zeros_like(x)
        e[j] = h
        Jfd[:, j] = (8.0 * (prob.residual(x + e) - prob.residual(x - e))
                     - (prob.residual(x + 2 * e) - prob.residual(x - 2 * e))) / (12 * h)
    scale = np.abs(J).max()
    assert np.max(np.abs(J - Jfd)) / scale < 1e-7
    assert np.max(np.abs(J[:, -1] - Jfd[:, -1])) / np.abs(J[:, -1]).max() < 1e-7
    if free == "both":
        assert J.shape == (x.size - 1, x.size)
        assert np.max(np.abs(J[:, -2] - Jfd[:, -2])) / np.abs(J[:, -2]).max() < 1e-7


def test_coarse_solve_at_1p2(params, pulse12):
    s = pulse12
    pu = s.to_pulse()
    assert pu.converged and pu.max_residual <= 1e-13
    # β and L of the N = 3200 solution (BENCHMARKS.md): 0.0072419, 1.07397 m; coarse grid is 2nd order
    assert pu.beta == pytest.approx(0.0072419, rel=3e-4)
    assert pu.L == pytest.approx(1.07397, rel=2e-3)
    # self-healing boundary conditions: v → v_stick at both ends, τ → τ_d
    assert abs(pu.v[0] / pu.v_stick - 1) < 1e-3 and abs(pu.v[-1] / pu.v_stick - 1) < 1e-3
    # τ → τ_d: behind within 1e-4; ahead the Hilbert far field decays like 1/ξ (≈2e-4 at 120 L)
    assert abs(pu.tau[0] / pu.tau_d - 1) < 1e-4 and abs(pu.tau[-1] / pu.tau_d - 1) < 1e-3
    ahead = pu.xi > pu.xi[np.argmax(pu.tau)] + 10 * pu.L
    assert np.all(np.diff(pu.tau[ahead]) < 0)
    # stress peak above τ_d ahead of the slip-rate peak; minimum below τ_d behind it
    k = int(np.argmax(pu.v))
    assert np.argmax(pu.tau) > k and pu.tau.max() > 1.3 * pu.tau_min
    assert pu.tau.min() < pu.tau_d
    assert pu.extra["n_humps"] == 1          # the fundamental pulse, not a two-hump bound state


def test_solution_satisfies_equation_with_independent_hilbert(params, pulse12):
    # re-evaluate the elastic stress with the linear-interpolant operator on a 3× refined grid
    pu = pulse12.to_pulse()
    xi = pu.xi
    fine = np.unique(np.concatenate([xi, *(xi[:-1] + f * np.diff(xi) for f in (1 / 3, 2 / 3))]))
    y = np.interp(fine, xi, np.log(pu.v))
    from scipy.interpolate import CubicSpline
    y = CubicSpline(xi, np.log(pu.v))(fine)
    u = np.exp(y) - pu.v_stick
    tau_el = pu.tau_d - params.mu * params.F3(pu.beta) * (hilbert_matrix(fine, "linear", center=0.0) @ u)
    near = (fine > xi[np.argmax(pu.v)] - 2 * pu.L) & (fine < xi[np.argmax(pu.v)] + pu.L)
    tau_fr = np.interp(fine, xi, pu.tau)
    assert np.max(np.abs(tau_el - tau_fr)[near]) / pu.tau_d < 2e-3


@pytest.mark.parametrize("L,beta,lc", [(0.35, 0.003, 5e-3), (2.0, 0.03, 15e-3), (0.7, 0.03, 1.5e-3)])
def test_guess_basin_is_not_a_knife_edge(params, L, beta, lc):
    g = default_guess(params, 1.2, 400, L=L, beta=beta, lc=lc)
    pu = solve_pulse(params, 1.2, n_points=500, guess=g, passes=1).to_pulse()
    assert pu.converged and pu.beta == pytest.approx(0.00724, rel=5e-3)


def test_hump_counter():
    from slippulse.steady.solver import count_humps
    x = np.linspace(-10, 10, 2001)
    one = 1e-7 + 1e-3 * np.exp(-x ** 2)
    two = one + 1e-4 * np.exp(-(x + 4) ** 2)
    assert count_humps(one) == 1 and count_humps(two) == 2


def test_hdf5_roundtrip_and_schema(params, pulse12, tmp_path):
    pu = pulse12.to_pulse()
    path = tmp_path / "p.h5"
    write_pulse(str(path), pu, params)
    back, p2 = read_pulse(str(path), "td1.2000")
    assert p2 == params
    assert np.array_equal(back.v, pu.v) and back.beta == pu.beta and back.converged
    with h5py.File(path, "r") as h5:
        for k in ("slippulse_version", "created"):
            assert k in h5.attrs
        assert h5["parameters"].attrs["mu_units"] == "Pa"
        assert h5["pulses/td1.2000/xi"].attrs["units"] == "m"
    with h5py.File(path, "r+") as h5:
        del h5["pulses/td1.2000"].attrs["beta"]
    with pytest.raises(SchemaError, match="beta"):
        read_pulse(str(path))


def test_nonconvergence_is_reported_not_hidden(params):
    s = solve_pulse(params, 1.2, n_points=300, tol=1e-30, passes=0)
    pu = s.to_pulse()
    assert not pu.converged and pu.extra["status"] == "failed"


def run_cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "slippulse.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("args,name", [
    (["--tau-d", "1.0"], "tau_d/tau_min"), (["--tau-d", "0.8"], "tau_d/tau_min"),
    (["--tau-d", "1.35"], "tau_d/tau_min"), (["--tau-d", "inf"], "tau-d"),
    (["--points", "10"], "points")])
def test_cli_bad_input_one_line_exit_2_no_file(tmp_path, args, name):
    out = tmp_path / "x.h5"
    import cli_inproc
    r = cli_inproc.run(["steady", "solve", *args, "--out", out, "-q"])
    assert r.returncode == 2
    assert name in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_cli_nonconvergence_exits_nonzero_and_marks_file(tmp_path):
    out = tmp_path / "x.h5"
    r = run_cli("steady", "solve", "--tol", "1e-16", "--points", "300", "--out", str(out), "-q",
                "--no-figure", cwd=tmp_path)
    assert r.returncode == 1 and "did not converge" in r.stderr
    pu, _ = read_pulse(str(out))
    assert pu.converged is False


def test_guess_state_is_the_order2_state_of_the_problem():
    """solver.guess_state (which lays out grids) is the order-2 state of a real SteadyProblem."""
    from slippulse.core.params import DEFAULT
    from slippulse.steady.equations import SteadyProblem
    from slippulse.steady.solver import default_guess, guess_state
    xi, y, beta = default_guess(DEFAULT, 1.1, 300)[:3]
    prob = SteadyProblem(DEFAULT, 1.1, xi, 0, 0.0, state_order=2)
    assert np.array_equal(guess_state(DEFAULT, 1.1, xi, np.exp(y), beta),
                          prob.state(np.exp(y), beta, False)[0])


def test_fused_jacobian_sweep_equals_the_dense_state_jacobian(params):
    """radau_jacobian_into fills H cv − fphi P − diag(dv) row by row from one row of P: the same
    numbers, bit for bit, as forming the dense P of integrate_state_radau first."""
    from slippulse.steady.equations import radau_jacobian_into
    xi, y, beta = default_guess(params, 1.1, 90)
    rng = np.random.default_rng(3)
    n = xi.size
    y = y + 0.01 * rng.standard_normal(n)
    H = hilbert_matrix(xi)
    cv, fphi, dv = rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(n)
    c = beta * params.c_s
    phi, P, dphi_dc, G = integrate_state_radau(xi, y, c, 2.0, params.v_star, params.D, RADAU_A,
                                               RADAU_C)
    dense = H * cv - fphi[:, None] * P
    dense[np.diag_indices(n)] -= dv
    J = np.full((n + 1, n + 2), np.nan)
    dc, g = radau_jacobian_into(xi, y, c, 2.0, params.v_star, params.D, (RADAU_A, RADAU_C), H,
                                (cv, fphi, dv), J)
    assert np.array_equal(J[:n, :n], dense)
    assert np.array_equal(dc, dphi_dc) and np.array_equal(g, G)
    assert np.isnan(J[n:, :]).all() and np.isnan(J[:, n:]).all()    # nothing outside the block
