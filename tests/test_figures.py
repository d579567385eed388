"""Smoke test of ``slippulse figures`` on a small synthetic family file.

The synthetic pulses are not solutions of the steady equation: v(ξ) is an analytic edge-singular
profile sized by the paper's scaling law, φ(ξ) integrates the state equation exactly at frozen rate
(the friction module's ``state_step``), τ = σ f(v, φ). They look like pulses, which is what a
figure smoke test needs; the numbers are tested in test_analysis.py.
"""
import numpy as np

from slippulse.steady import analysis as an
from slippulse import cli
from slippulse.core import h5io
from slippulse.plotting import steady as plotting
from slippulse.core import friction as fr
from slippulse.core.params import DEFAULT

PAPER = dict(tau_star=1.0087, a_v=1.15, a_G=0.69)


def synthetic_pulse(ratio, params=DEFAULT, domain=20.0, seed=0):
    """A pulse-like field set at τ_d = ratio τ_min (see module docstring)."""
    prm = params
    beta, Lt = an.scaling_law(ratio, params=prm, **PAPER)
    beta, L = float(beta), float(Lt) * prm.L_Gc
    a = L / 300.0                                    # edge regularisation length
    v0 = PAPER["a_v"] * prm.v_min
    tau_d = ratio * prm.tau_min
    vs = prm.v_stick(tau_d)
    # grid: spacing a/20 at the edge ξ_p = 0, geometric growth 4 % per cell, `domain` L each way
    h = a / 20.0
    right, left = [0.0], [0.0]
    while right[-1] < domain * L:
        right.append(right[-1] + h * 1.04 ** (len(right) - 1))
    while left[-1] > -domain * L:
        left.append(left[-1] - h * 1.04 ** (len(left) - 1))
    xi = np.array(left[::-1] + right[1:])
    r = -xi                                          # distance behind the edge
    edge = (r * r + a * a) ** -0.25 * 0.5 * (1 + np.tanh(r / a)) * np.sqrt(L)
    body = 0.5 * (1 - np.tanh((r - L) / (0.15 * L)))
    tail = 0.05 * np.exp(-np.clip(r - L, 0, None) / (3 * L)) * 0.5 * (1 + np.tanh((r - L) / a))
    v = vs + v0 * (edge * body + tail)
    # state: −βc_s dφ/dξ = g, exact at frozen rate, from the rest state ahead backwards
    phi = np.empty_like(v)
    phi[-1] = fr.phi_ss(vs, prm.v_star, prm.D)
    dt = np.diff(xi) / (beta * prm.c_s)
    vm = 0.5 * (v[1:] + v[:-1])
    w = fr.heal_rate(vm, prm.v_star, prm.D)
    for i in range(xi.size - 2, -1, -1):
        phi[i] = fr.state_step(phi[i + 1], w[i], dt[i])
    tau = prm.sigma * fr.f(v, phi, *prm.law_args)
    rng = np.random.default_rng(seed)
    res = 1e-15 * rng.standard_normal(xi.size)
    return h5io.Pulse(xi=xi, v=v, phi=phi, tau=tau, residual=res, tau_d_ratio=ratio, tau_d=tau_d,
                      tau_min=prm.tau_min, beta=beta, c_p=beta * prm.c_s, L=L,
                      L_tilde=L / prm.L_Gc, v_stick=vs, v_max=float(v.max()),
                      max_residual=float(np.abs(res).max()), converged=True, n_points=xi.size,
                      wall_time=0.0)


def make_synthetic_family(path, ratios=(1.2, 1.1, 1.05, 1.03, 1.02, 1.015), params=DEFAULT):
    for r in ratios:
        h5io.write_pulse(path, synthetic_pulse(r, params, seed=int(round(r * 1e4))), params)
    return path


def _is_png(path):
    with open(path, "rb") as fh:
        return fh.read(8) == b"\x89PNG\r\n\x1a\n"


def _is_pdf(path):
    with open(path, "rb") as fh:
        return fh.read(5) == b"%PDF-"


def test_figures_command_writes_every_figure(tmp_path, capsys):
    fam = make_synthetic_family(str(tmp_path / "fam.h5"))
    out = tmp_path / "figs"
    rc = cli.main(["figures", fam, "--outdir", str(out)])
    assert rc == 0
    for name in plotting.FIGURES:
        png, pdf = out / f"{name}.png", out / f"{name}.pdf"
        assert png.stat().st_size > 10_000 and _is_png(png), name
        assert pdf.stat().st_size > 5_000 and _is_pdf(pdf), name
    assert sorted(p.name for p in out.iterdir()) == sorted(
        f"{n}.{e}" for n in plotting.FIGURES for e in ("png", "pdf"))


def test_figures_with_comparison_file_and_bad_input(tmp_path, capsys):
    fam = make_synthetic_family(str(tmp_path / "fam.h5"), ratios=(1.2, 1.05))
    other = str(tmp_path / "long.h5")
    h5io.write_pulse(other, synthetic_pulse(1.05, domain=60.0), DEFAULT)
    out = tmp_path / "figs"
    assert cli.main(["figures", fam, "--outdir", str(out), "--compare", other,
                     "--formats", "png"]) == 0
    assert _is_png(out / "figS1.png") and not (out / "figS1.pdf").exists()
    assert cli.main(["figures", str(tmp_path / "missing.h5")]) == 2
    assert cli.main(["figures", fam, "--formats", "gif"]) == 2
    assert "error" in capsys.readouterr().err
