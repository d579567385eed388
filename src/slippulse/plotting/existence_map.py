"""Chart of :func:`slippulse.steady.existence_map.existence_map`: where pulses exist over (b, α)
and where the solver finds them (from the built-in guess; by continuation in the parameters)."""
from __future__ import annotations

import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from .metadata import params_metadata
from ..core.atomic import save_figure
from ..steady.existence_map import ABOVE_PEAK, FAILED, FOUND, NO_N_SHAPE, NOT_TRIED

_COLORS = {NO_N_SHAPE: "#9e9e9e", ABOVE_PEAK: "#d9d9d9", FAILED: "#f4a582", FOUND: "#92c5de",
           NOT_TRIED: "#ffffff"}


def short_reason(reason: str) -> str:
    """A few characters for a failure cell: NC (Newton not converged), LS (line search failed),
    H<n> (n humps), β (β out of range), L (no length), EX (exception)."""
    if reason.startswith("newton: line search"):
        return "LS"
    if reason.startswith("newton"):
        return "NC"
    if reason.startswith("humps="):
        return "H" + reason[6:]
    if reason.startswith("beta"):
        return "β"
    if reason.startswith("no length"):
        return "L"
    return "EX"


def plot_existence_map(m, path: str, dpi: int = 150) -> str:
    """Two panels (built-in guess | continuation) over (b, α): cell colour = outcome, text = β and
    L/L0 where the pulse was found, the failure code where not; τ_peak/τ_min contour where the
    fixed τ_d/τ_min leaves the N."""
    fig = Figure(figsize=(12.0, 5.6))
    axes = fig.subplots(1, 2, sharey=True)
    codes = [NO_N_SHAPE, ABOVE_PEAK, FAILED, FOUND, NOT_TRIED]
    cmap = ListedColormap([_COLORS[c] for c in codes])
    nb, na = m.b.size, m.alpha.size
    for ax, status, reason, title in ((axes[0], m.guess_status, m.guess_reason,
                                       "(a) from the built-in guess"),
                                      (axes[1], m.cont_status, m.cont_reason,
                                       "(b) by continuation in (b, α) from Table I")):
        idx = np.vectorize(codes.index)(status)
        ax.imshow(idx.T, origin="lower", cmap=cmap, vmin=-0.5, vmax=len(codes) - 0.5,
                  aspect="auto", extent=(-0.5, nb - 0.5, -0.5, na - 0.5))
        for i in range(nb):
            for j in range(na):
                s = status[i, j]
                if s == FOUND:
                    txt = f"β={m.beta[i, j]:.3g}\nL/L0={m.L_over_L0[i, j]:.3g}"
                elif s == FAILED:
                    txt = short_reason(str(reason[i, j]))
                else:
                    txt = ""
                ax.text(i, j, txt, ha="center", va="center", fontsize=6.5)
                if m.b[i] == m.base.b and m.alpha[j] == m.base.alpha:
                    ax.add_patch(Rectangle((i - 0.5, j - 0.5), 1, 1, fill=False, lw=2, ec="k"))
        ax.set_xticks(range(nb), [f"{v:g}" for v in m.b])
        ax.set_yticks(range(na), [f"{v:g}" for v in m.alpha])
        ax.set_xlabel("b (state coefficient)")
        ax.set_title(title, fontsize=10)
    axes[0].set_ylabel("α (rate-strengthening coefficient)")
    handles = [axes[1].fill_between([], [], color=_COLORS[c], ec="0.5") for c in codes]
    fig.legend(handles, ["τ_ss not N-shaped", f"τ_d/τ_min = {m.tau_d_ratio:g} ≥ τ_peak/τ_min",
                         "solver failed (NC: Newton not converged, LS: line search failed, "
                         "Hn: converged to n humps)", "pulse found (β, L/L0)",
                         "not reached (no solved neighbour)"],
               loc="lower center", ncol=3, fontsize=8, frameon=False)
    fig.suptitle(f"Steady pulses at τ_d/τ_min = {m.tau_d_ratio:g} over (b, α), other parameters "
                 f"Table I, N = {m.n_points} (square: Table I)", fontsize=10)
    fig.subplots_adjust(bottom=0.2, top=0.9, wspace=0.05)
    save_figure(fig, path, dpi=dpi, metadata=params_metadata(m.base, path))
    return path
