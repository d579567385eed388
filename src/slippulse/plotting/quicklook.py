"""Quick-look figures of single runs (the steady pulse of ``slippulse steady solve``)."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .metadata import params_metadata  # noqa: E402

from ..core.atomic import save_figure


def plot_pulse(pulse, params, path):
    """Slip rate and shear stress of a steady pulse vs ξ/L0, near field and whole domain."""
    x = pulse.xi / params.L0
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), sharex="col")
    k = int(np.argmax(pulse.v))
    xl = (x[k] - 3.0 * pulse.L / params.L0, x[k] + 1.0 * pulse.L / params.L0)
    for col, lim in enumerate([xl, None]):
        ax = axes[0, col]
        ax.semilogy(x, pulse.v, lw=1.2)
        ax.axhline(pulse.v_stick, ls=":", c="0.5", label=r"$v_{\rm stick}$")
        ax.set_ylabel(r"$v$ (m/s)")
        ax = axes[1, col]
        ax.plot(x, pulse.tau / pulse.tau_min, lw=1.2, c="C3")
        ax.axhline(pulse.tau_d_ratio, ls=":", c="0.5", label=r"$\tau_{\rm d}$")
        ax.axhline(1.0, ls="--", c="0.7", lw=0.8, label=r"$\tau_{\rm min}$")
        ax.set_ylabel(r"$\tau/\tau_{\rm min}$")
        ax.set_xlabel(r"$\xi/L_0$   ($L_0$ = %.3f m)" % params.L0)
        if lim is not None:
            for a in axes[:, col]:
                a.set_xlim(*lim)
        else:
            for a in axes[:, col]:
                a.set_xscale("symlog", linthresh=pulse.L / params.L0)
    axes[0, 0].legend(loc="upper left")
    axes[1, 0].legend(loc="upper left")
    axes[0, 0].set_title("near the pulse")
    axes[0, 1].set_title("whole domain (symlog ξ)")
    fig.suptitle(r"steady pulse $\tau_{\rm d}/\tau_{\rm min}$ = %.4f: $\beta$ = %.5g, $L$ = %.4g m, "
                 r"max$|\Delta|$ = %.1e, N = %d" % (pulse.tau_d_ratio, pulse.beta, pulse.L,
                                                  pulse.max_residual, pulse.n_points))
    fig.tight_layout()
    save_figure(fig, path, dpi=110, metadata=params_metadata(params, path))
    plt.close(fig)
    return path
