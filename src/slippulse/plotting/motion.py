"""The (L, c_p) plane: the steady line, measured trajectories and the equation of motion's
predictions started from the same states (docs/motion.md)."""
from __future__ import annotations

import numpy as np


def motion_figure(path: str, line, comparisons: dict, title: str = "") -> None:
    """Left: c_p/c_s against L (log) with the steady line (pulses as dots) and, per run, the
    measurement (solid) and the model (dashed, band shaded). Right: L(t) against the distance
    travelled, measured and modelled, the 5 % split marked. ``comparisons``: label →
    timedomain.motion.Comparison."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.4))
    cs = line.c_s
    Lg = np.geomspace(line.L[0], line.L[-1], 300)
    a.plot(Lg, line.functions()[2](Lg) / cs, color="0.5", lw=2, label="steady line")
    a.plot(line.L, line.c_p / cs, "o", color="0.5", ms=3)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (lab, cmp_) in enumerate(comparisons.items()):
        col = colors[i % len(colors)]
        m = cmp_.model
        a.plot(cmp_.L, cmp_.c_p / cs, "-", color=col, lw=1.2, label=f"SBI {lab}")
        a.plot(m.L, m.c_p / cs, "--", color=col, lw=1.2)
        a.plot(cmp_.L[cmp_.skip], cmp_.c_p[cmp_.skip] / cs, "o", color=col, ms=4)
        d = cmp_.x / cmp_.L[0]
        b.plot(d, cmp_.L, "-", color=col, lw=1.2, label=f"SBI {lab}")
        b.plot(d, m.L, "--", color=col, lw=1.2)
        b.fill_between(d, m.L_lo, m.L_hi, color=col, alpha=0.2, lw=0)
        if np.isfinite(cmp_.t_split):
            k = int(np.searchsorted(cmp_.t, cmp_.t_split))
            b.plot(d[k], cmp_.L[k], "x", color=col, ms=8)
    a.set_xscale("log")
    a.set_yscale("log")
    a.set_xlabel("L (m)")
    a.set_ylabel("c_p / c_s")
    a.legend(fontsize=7)
    a.set_title("trajectories (solid: SBI, dashed: model)", fontsize=9)
    b.set_xlabel("distance travelled / L(0)")
    b.set_ylabel("L (m)")
    b.set_yscale("log")
    b.set_title("L against distance; model (dashed) from the dot (L 1 % from L*),\n"
                "band s ± s_err and interpolation; x: first 5 % difference in L or c_p",
                fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def profiles_figure(path: str, run: dict, v_star: float, c_s: float, title: str = "") -> None:
    """A fate run's shape: left, ln(v/v* + 1) of its stored snapshots against x − x_front (in
    L⁰), the half-maximum of each marked; right, the front and the rear half-maximum edge
    (x_front − L) in the lab frame against t, with ±c_s slopes: a rear edge running backward is
    a slipping region growing at both ends (crack-like). ``run``: ``timedomain.fate.read_fate``
    with ``snapshots`` (t, xi_rel, v)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    L0 = float(run["L0"])
    snaps = run.get("snapshots")
    cmap = plt.get_cmap("viridis")
    if snaps is not None:
        n = len(snaps["t"])
        for i in range(n):
            xi, y = snaps["xi_rel"][i] / L0, np.log(snaps["v"][i] / v_star + 1.0)
            k = np.argsort(xi)
            col = cmap(i / max(n - 1, 1))
            a.plot(xi[k], y[k], color=col, lw=1, label=f"t = {snaps['t'][i] * 1e3:.3g} ms")
            a.axhline(0.5 * y.max(), color=col, lw=0.5, ls=":")
    a.set_xlabel("(x − x_front) / L⁰")
    a.set_ylabel("ln(v/v* + 1)")
    if snaps is not None and len(snaps["t"]):
        a.legend(fontsize=7)
        a.set_title("slip-rate snapshots (dotted: half maximum)", fontsize=9)
    else:
        a.set_title("no slip-rate snapshots stored", fontsize=9)
    t, x, L = run["t"] * 1e3, run["x_front"], run["L"]
    b.plot(t, (x - x[0]) / L0, label="front")
    b.plot(t, (x - L - x[0]) / L0, label="rear half-maximum edge")
    for end, sgn in ((x[-1], 1.0), (x[-1] - L[-1], -1.0)):     # ±c_s through the last points
        tt = np.array([t[-1] - 0.1 * (t[-1] - t[0]), t[-1]])
        b.plot(tt, (end - x[0] + sgn * c_s * (tt - t[-1]) / 1e3) / L0, color="0.6", lw=0.8,
               ls="--")
    b.set_ylim(((x - L).min() - x[0]) / L0 - 0.5, (x.max() - x[0]) / L0 + 0.5)
    b.set_xlabel("t (ms)")
    b.set_ylabel("lab position / L⁰")
    b.legend(fontsize=7)
    b.set_title("edges in the lab frame (dashed: ±c_s)", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
