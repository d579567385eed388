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
from slippulse.core.reference import paper_scaling

PAPER = paper_scaling()


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


def _pixels_near(img, x, y, color, r=3, tol=0.08):
    """Does the image (rows top-down, RGB(A) in [0, 1]) hold a pixel of ``color`` within r pixels
    of the display point (x, y) (origin bottom-left)?"""
    h = img.shape[0]
    row, col = int(round(h - y)), int(round(x))
    patch = img[max(row - r, 0):row + r + 1, max(col - r, 0):col + r + 1, :3]
    return bool(np.any(np.all(np.abs(patch - np.asarray(color)) < tol, axis=-1)))


def test_fig3_png_draws_the_pulses_where_the_data_says(tmp_path):
    """Content, not size: the figure's lines hold the family's β and L-tilde, and in the written
    PNG the β markers (colour C0) sit at the pixels the data maps to, and nowhere else in the plot
    area (moving the data by 0.15 in β finds none)."""
    from matplotlib.colors import to_rgb
    from matplotlib.image import imread
    fam = make_synthetic_family(str(tmp_path / "fam.h5"))
    data = plotting.load_family(fam)
    fig = plotting.fig3(data)
    ax, ax2 = fig.axes[0], fig.axes[1]
    x = np.array([r["tau_d_ratio"] for r in data.rows])
    beta = np.array([r["beta"] for r in data.rows])
    Lt = np.array([r["L_tilde"] for r in data.rows])
    pulses = [ln for ln in ax.get_lines() if ln.get_label() == r"$\beta$ (pulses)"][0]
    assert np.array_equal(pulses.get_xdata(), x) and np.array_equal(pulses.get_ydata(), beta)
    assert np.array_equal(ax2.get_lines()[0].get_ydata(), Lt)
    paper = [ln for ln in ax.get_lines() if ln.get_label().startswith(r"$\beta$, paper's")][0]
    xp = np.asarray(paper.get_xdata())
    assert np.allclose(paper.get_ydata(), an.scaling_law(xp, params=data.params, **PAPER)[0],
                       rtol=1e-12)
    png = tmp_path / "fig3.png"
    fig.savefig(png, dpi=100)
    img = imread(png)
    c0 = to_rgb("C0")
    pts = ax.transData.transform(np.column_stack([x, beta]))
    assert all(_pixels_near(img, px, py, c0) for px, py in pts)
    off = ax.transData.transform(np.column_stack([x, np.clip(beta + 0.15, 0, 0.95)]))
    inside = [(px, py) for (px, py), b in zip(off, beta) if b + 0.15 < 0.6]   # below the legend
    assert inside and not any(_pixels_near(img, px, py, c0) for px, py in inside)


def test_fig3_gives_each_curve_its_own_legend_entry(tmp_path):
    """β and L-tilde by the paper's constants are two dotted curves on two axes: two legend
    entries, each in its axis' colour (they shared one grey entry)."""
    from matplotlib.colors import to_rgba
    fam = make_synthetic_family(str(tmp_path / "fam.h5"))
    fig = plotting.fig3(plotting.load_family(fam))
    ax, ax2 = fig.axes[0], fig.axes[1]
    legend = ax.get_legend()
    entries = {t.get_text(): h for t, h in zip(legend.get_texts(), legend.legend_handles)}
    drawn = [ln for a in (ax, ax2) for ln in a.get_lines() if not ln.get_label().startswith("_")]
    assert len(drawn) == len(entries) and {ln.get_label() for ln in drawn} == set(entries)
    dotted = [ln for ln in drawn if ln.get_linestyle() == ":"]
    assert len(dotted) == 2
    assert len({to_rgba(ln.get_color()) for ln in dotted}) == 2
