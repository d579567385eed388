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
