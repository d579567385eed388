"""Figures of the stability layer: ±ε perturbation scans (growth, trajectories in the (L, c_p)
plane, modes) and verification runs of seeded pulses (``slippulse dynamic verify``)."""
from __future__ import annotations

import os

import numpy as np
from matplotlib.figure import Figure

from ..core.atomic import save_figure
from ..steady.measures import pulse_length
from ..timedomain.perturbation import (pair_table, read_series, smoothed_c_p, steady_curve,
                                      write_pair_table)
from ..timedomain.verify import VerifyResult, drift_verdict, mode_growth
from .metadata import params_metadata
from .steady import matplotlib_cmap


def scan_figures(rows: list[dict], out_dir: str) -> list[str]:
    """Figures hook of the perturbation runner's scans: the pair table (growth_pairs.csv,
    :func:`slippulse.timedomain.perturbation.write_pair_table`) and :func:`stability_figures`."""
    return write_pair_table(rows, out_dir) + stability_figures(rows, pair_table(rows), out_dir)


# --------------------------------------------------------------------------------------------
# ±ε perturbation scans (``slippulse dynamic scan``)

def stability_figures(rows, pairs, out_dir, dpi=130, prefix="stab_", extra_steady=()):
    """Figures of a perturbation scan; returns the paths.

    File names start with ``prefix``:

    * ``stab_deviation.png``: |v_max/v_max⁰ − 1| against the distance travelled (in L⁰), every
      run (solid +ε, dashed −ε), coloured by τ_d;
    * ``stab_trajectories.png``: each run in the (L, c_p/c_s) plane over the steady curve β(L) of
      its steady family file;
    * ``stab_modes.png``: the unstable mode of each ±ε pair (antisymmetric deviation of
      ln(v/v*+1) per unit v_max deviation, co-moving frame), ``stability.pair_growth``.
    """
    os.makedirs(out_dir, exist_ok=True)
    runs = [r for r in rows if r.get("file") and os.path.exists(str(r["file"]))]
    if not runs:
        return []
    ratios = sorted({round(float(r["tau_d_ratio"]), 6) for r in runs})
    cmap = matplotlib_cmap("viridis")
    colour = {q: cmap(i / max(1, len(ratios) - 1)) for i, q in enumerate(ratios)}
    series = {r["file"]: read_series(r["file"]) for r in runs}
    written = []

    fig = Figure(figsize=(6.4, 4.2))
    ax = fig.add_subplot()
    for r in runs:
        s = series[r["file"]]
        ls = "-" if float(r["eps"]) > 0 else ("--" if float(r["eps"]) < 0 else ":")
        ax.semilogy(s["distance"], np.abs(s["v_max_error"]), ls=ls, lw=0.9,
                    color=colour[round(float(r["tau_d_ratio"]), 6)])
    for q in ratios:
        ax.plot([], [], color=colour[q], label=f"τ_d = {q:.4g} τ_min")
    ax.plot([], [], "k-", label="+ε")
    ax.plot([], [], "k--", label="−ε")
    ax.set_xlabel("distance travelled / L⁰")
    ax.set_ylabel("|v_max/v_max⁰ − 1|")
    ax.set_ylim(1e-6, 30)
    ax.legend(fontsize=7)
    fig.tight_layout()
    written.append(os.path.join(out_dir, f"{prefix}deviation.png"))
    save_figure(fig, written[-1], dpi=dpi)

    fig = Figure(figsize=(6.4, 4.6))
    ax = fig.add_subplot()
    steady_files = sorted({str(r["steady"]) for r in runs if r.get("steady")} | set(extra_steady))
    cur = steady_curve(*[p for p in steady_files if os.path.exists(p)])
    cur = cur[np.argsort(cur[:, 2])]                  # along the family (τ_d), not by L
    ax.plot(cur[:, 0], cur[:, 3], "k-", lw=3, alpha=0.3, label="steady pulses β(L)")
    for r in runs:
        s = series[r["file"]]
        cs = float(s["attrs"]["c_p"]) / float(s["attrs"]["beta"])
        cp = smoothed_c_p(s)
        ls = "-" if float(r["eps"]) > 0 else "--"
        ax.plot(s["L"][2:-2], cp[2:-2] / cs, ls=ls, lw=1,
                color=colour[round(float(r["tau_d_ratio"]), 6)])
        ax.plot([s["attrs"]["L"]], [s["attrs"]["beta"]], "o", ms=4,
                color=colour[round(float(r["tau_d_ratio"]), 6)])
    for q in ratios:
        ax.plot([], [], color=colour[q], label=f"τ_d = {q:.4g} τ_min (dot: the steady pulse)")
    ax.plot([], [], "k-", lw=1, label="+ε")
    ax.plot([], [], "k--", lw=1, label="−ε")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("pulse length L (m)")
    ax.set_ylabel("c_p / c_s")
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    written.append(os.path.join(out_dir, f"{prefix}trajectories.png"))
    save_figure(fig, written[-1], dpi=dpi)

    modes = [p for p in pairs if p["_growth"].get("mode") is not None]
    if modes:
        taus = sorted({round(float(p["tau_d_ratio"]), 6) for p in modes}, reverse=True)
        fig = Figure(figsize=(3.2 * len(taus) + 0.6, 3.8))
        axes = np.atleast_1d(fig.subplots(1, len(taus), sharey=False))
        for ax, q in zip(axes, taus):
            for p in modes:
                if round(float(p["tau_d_ratio"]), 6) != q:
                    continue
                g = p["_growth"]
                ax.plot(g["mode_xi"], g["mode"], lw=1,
                        label=f"ε={p['eps']:g}, Δx={1e3 * float(p['dx']):g} mm, "
                              f"{float(p['behind']):g}+{float(p['ahead']):g} L, {p['history']}")
            ax.set_title(f"τ_d = {q:.4g} τ_min", fontsize=9)
            ax.set_xlabel("(ξ − ξ_front)/L⁰")
            ax.legend(fontsize=5)
        axes[0].set_ylabel("δ ln(v/v*+1) per unit δv_max/v_max")
        fig.tight_layout()
        written.append(os.path.join(out_dir, f"{prefix}modes.png"))
        save_figure(fig, written[-1], dpi=dpi)
    return written


def growth_figure(pairs, path: str, dpi=130) -> str:
    """The measured growth rates of ±ε pairs (:func:`pair_table` rows with ``variant``) against
    τ_d: per pulse length (left) and per second (right); the base pair of each τ_d in black,
    its variants (grid, ε, domain, history) in orange. Returns ``path``."""
    fig = Figure(figsize=(6.4, 4.0))
    ax, bx = fig.subplots(1, 2)
    for p in pairs:
        if not np.isfinite(p["s_per_L"]):
            continue
        base = p["variant"] == "base"
        for a, k in ((ax, "s_per_L"), (bx, "s_per_s")):
            a.errorbar(p["tau_d_ratio"], p[k], yerr=p[k + "_err"], fmt="o" if base else ".",
                       ms=5, color="k" if base else "C1")
    for a, lab in ((ax, "growth rate s·L/c_p (per pulse length)"), (bx, "growth rate s (1/s)")):
        a.axhline(0, color="0.6", lw=0.8)
        a.set_xlabel("τ_d/τ_min")
        a.set_ylabel(lab)
    ax.plot([], [], "ko", label="base pair")
    ax.plot([], [], ".", color="C1", label="refined / other ε, domain, history")
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=dpi)
    return path


def plot_verify_result(path_png: str, res: VerifyResult, pulse, params) -> None:
    """The verification figure (PNG), three panels against the steady pulse:

    (a) v(ξ − ξ_front) at t = 0 and at the end over the steady profile (log scale);
    (b) the deviation ln(v/v*+1) − steady against (ξ − ξ_front)/L⁰ at up to 9 measurement times,
        coloured by the distance travelled;
    (c) |v_max error| against the distance d travelled (log axis), with the growth e^{s d} of the
        unstable mode (:func:`mode_growth`) drawn over it where s is known, through the samples of
        the fit window of :func:`growth_rate`; the title gives :func:`drift_verdict`.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    _, _, xi_front = pulse_length(pulse.xi, pulse.v, params.v_star)
    L = pulse.L
    dist = np.asarray(res.series["distance"], dtype=float)
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 10.5))
    # (a) profiles
    ax = axes[0]
    sel = (pulse.xi - xi_front > -3 * L) & (pulse.xi - xi_front < 1.5 * L)
    ax.semilogy((pulse.xi[sel] - xi_front) / L, pulse.v[sel], "k-", lw=4, alpha=0.25,
                label="steady")
    for (t, xr, V), style in zip((res.snapshots[0], res.snapshots[-1]), ("C0--", "C3-")):
        o = np.argsort(xr)
        w = (xr[o] > -3 * L) & (xr[o] < 1.5 * L)
        ax.semilogy(xr[o][w] / L, V[o][w], style, lw=1.2,
                    label=f"SBI, d = {t * pulse.c_p / L:.3g} L")
    ax.set_xlabel("(ξ − ξ_front)/L⁰")
    ax.set_ylabel("v (m/s)")
    ax.set_title("(a) slip rate: start and end of the run over the steady pulse", fontsize=9)
    ax.legend(fontsize=8)
    # (b) deviation field
    ax = axes[1]
    dev = np.asarray(res.series.get("deviation", np.empty((0, 0))))
    if dev.size:
        rel = np.asarray(res.series["deviation_xi"])
        picks = np.unique(np.round(np.linspace(0, dev.shape[0] - 1, min(9, dev.shape[0]))))
        cmap = plt.get_cmap("viridis")
        dmax = max(float(np.nanmax(dist)), 1e-300)
        for j in picks.astype(int):
            ax.plot(rel, dev[j], color=cmap(dist[j] / dmax), lw=1.1)
        sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(0.0, dmax))
        fig.colorbar(sm, ax=ax, label="distance travelled d (L⁰)")
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.set_xlabel("(ξ − ξ_front)/L⁰")
    ax.set_ylabel("ln(v/v*+1) − steady")
    ax.set_title("(b) deviation from the steady pulse in the frame of the front", fontsize=9)
    # (c) v_max error against distance, and the mode's growth
    ax = axes[2]
    err = np.abs(np.asarray(res.series["v_max_error"], dtype=float))
    ok = np.isfinite(err) & (err > 0)
    ax.semilogy(dist[ok], err[ok], "C0o-", ms=3, lw=1, label="|v_max/v_max⁰ − 1| (SBI)")
    known = mode_growth(res.info)
    if known is not None and ok.sum() >= 2:
        sv, serr, how = known
        win = ok & (err >= 3e-4) & (err <= 3e-2)          # growth_rate's fit window
        base = win if win.sum() >= 3 else ok & (dist >= 0.5 * np.nanmax(dist))
        lnA = float(np.mean(np.log(err[base]) - sv * dist[base]))
        dd = np.linspace(0.0, float(np.nanmax(dist)), 200)
        ax.semilogy(dd, np.exp(lnA + sv * dd), "k--", lw=1.2,
                    label=f"e^(s d), unstable mode s = {sv:.4g}"
                    + (f" ± {serr:.1g}" if np.isfinite(serr) else "") + " per L (eigenvalue)")
    ax.set_xlabel("distance travelled d (L⁰)")
    ax.set_ylabel("|v_max error|")
    verdict, text = drift_verdict(res)
    tag = {True: "drift = unstable mode (physics)", False: "drift NOT the unstable mode",
           None: "drift not attributed"}[verdict]
    ax.set_title(f"(c) v_max drift against distance: {tag}", fontsize=9)
    ax.legend(fontsize=8, loc="upper left")
    e = res.errors
    fig.suptitle(f"verify τ_d = {pulse.tau_d_ratio:.4g} τ_min, {res.info['travelled']:.3g} L: "
                 f"c_p err {e['c_p_error']:.1e}, v_max err {e['v_max_error']:.1e}\n"
                 + _wrap(text, 95), fontsize=9)
    fig.tight_layout()
    save_figure(fig, path_png, dpi=110, metadata=params_metadata(params, path_png))
    plt.close(fig)


def _wrap(text: str, width: int) -> str:
    import textwrap
    return "\n".join(textwrap.wrap(text, width))


# --------------------------------------------------------------------------------------------
# the steady line as attractor (``slippulse dynamic attractor``)

def attractor_figure(series, path: str, sbi=(), line=(), clip: float = 1.5, dpi=110) -> str:
    """Overlap of the unstable mode with the family tangent (left) and the departure fraction
    f (right) against τ_d (docs/stability.md §4). Returns ``path``.

    Parameters
    ----------
    series : list of (name, rows)
        :func:`slippulse.timedomain.eigenmode.family_overlaps` rows (or those of
        ``attractor.read_overlap_csv``), one style per series; with one series the overlap of
        y = ln(v/v*+1) alone is drawn too.
    sbi : list of dict
        :func:`slippulse.timedomain.attractor.sbi_departures`: f measured by eigenmode-seeded pairs.
    line : list of dict
        :func:`slippulse.timedomain.attractor.base_pair_departures`: the median
        |c_p/c_p⁰(L) − 1| of a scan's base ±ε runs along their whole trajectory.
    clip : float
        f is drawn clipped to [−clip, clip] (it diverges where the mode leaves c_p unchanged).
    """
    fig = Figure(figsize=(11, 4.3))
    ax, bx = fig.subplots(1, 2)
    marks = ["o-", "s-", "^-", "d-"]
    for i, (name, rows) in enumerate(series):
        rows = sorted(rows, key=lambda r: float(r["tau_d_ratio"]))
        q = np.array([float(r["tau_d_ratio"]) for r in rows])
        ax.plot(q, [float(r["overlap"]) for r in rows], marks[i % 4], ms=5,
                label=f"{name}: y and ln φ" if len(series) == 1 else name)
        if len(series) == 1:
            ax.plot(q, [float(r["overlap_y"]) for r in rows], "s--", ms=4,
                    label=f"{name}: y = ln(v/v*+1) only")
        f = np.array([float(r["departure_fraction"]) for r in rows])
        bx.plot(q, np.clip(f, -clip, clip), marks[i % 4], ms=5, label=f"eigenmode, {name}")
    if sbi:
        bx.plot([r["tau_d_ratio"] for r in sbi],
                np.clip([r["departure_fraction"] for r in sbi], -clip, clip), "k*", ms=12,
                label="SBI, eigenmode-seeded ±ε pairs (measured)")
    line = [r for r in line if np.isfinite(r["plus"]) or np.isfinite(r["minus"])]
    for i, r in enumerate(line):
        bx.plot([r["tau_d_ratio"]] * 2, [r["plus"], r["minus"]], "rv", ms=6,
                label="SBI ±ε runs: median |c_p/c_p⁰(L) − 1| to the fate" if i == 0 else None)
    ax.set_xlabel("τ_d/τ_min")
    ax.set_ylabel("overlap |⟨m, t⟩| / (‖m‖ ‖t‖)")
    ax.set_ylim(0, 1.05)
    ax.set_title("unstable eigenmode m vs family tangent t = d(y, ln φ)/dτ_d\n"
                 "(front frame, translation removed, ζ ∈ [−1.5, 0.5] L)", fontsize=9)
    ax.legend(fontsize=8)
    bx.axhline(0, color="0.6", lw=0.6)
    bx.axhline(1, color="0.8", lw=0.6, ls=":")
    bx.set_xlabel("τ_d/τ_min")
    bx.set_ylabel(f"departure fraction f (drawn within ±{clip:g})")
    bx.set_title("c_p/c_p⁰(L) − 1 ≈ f · δ ln c_p (0: along the steady line;\n"
                 "1: c_p changes at fixed L; > 1: L and c_p move oppositely)", fontsize=9)
    bx.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=dpi)
    return path
