"""The instability study of docs/stability.md: steady family, one scan per τ_d, the report.

Run (from the repository root)::

    python dynamic/stability.py family     # runs/family_stab.h5: 1.2 → 1.03 τ_min, N = 3000 (~1 min),
                                           # runs/family_up.h5: 1.3 → 1.2 (the steady line's other end)
    slippulse dynamic scan dynamic/scans/growth_td1.20.toml    # one command per row of the table
    slippulse dynamic scan dynamic/scans/growth_td1.10.toml
    slippulse dynamic scan dynamic/scans/growth_td1.05.toml
    slippulse dynamic scan dynamic/scans/growth_td1.03.toml
    python dynamic/stability.py report     # the table s(τ_d) and the figures of docs/stability.md

``report`` reads each scan's summary (runs/scans/<name>/summary.csv, written by the scan), pairs the
±ε runs (``stability.pair_table``), prints the markdown table of docs/stability.md and writes
docs/figures/stability_{growth,trajectories,modes,deviation}.png.
"""
from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np

FAMILY = "runs/family_stab.h5"
UPPER = "runs/family_up.h5"          # the branch 1.3 → 1.2 τ_min (L has its minimum near 1.29)
SCANS = ("growth_td1.20", "growth_td1.10", "growth_td1.05", "growth_td1.03")
FIG_DIR = "docs/figures"


def family():
    from slippulse.steady.continuation import run_family
    from slippulse.core.params import DEFAULT
    print(run_family(DEFAULT, FAMILY, start=1.2, stop=1.03, step=0.005, n_points=3000))
    print(run_family(DEFAULT, UPPER, start=1.3, stop=1.2, step=0.01, n_points=3000))


def _rows(name):
    """Rows of the finished cases of scan ``name`` (dynamic/scans/NAME.toml)."""
    from slippulse.timedomain.perturbation import scan_rows
    from slippulse.timedomain.scan import load_scan
    return scan_rows(load_scan(os.path.join("dynamic", "scans", name + ".toml")))


def report():
    from slippulse.plotting.stability import stability_figures
    from slippulse.timedomain.perturbation import pair_table, pair_variant

    all_rows, table = [], []
    for name in SCANS:
        rows = _rows(name)
        if not rows:
            print(f"(no results for {name})")
            continue
        all_rows += rows
        pairs = pair_table(rows)
        if not pairs:
            continue
        base = pairs[0]
        wall = sum(float(r.get("wall_time", 0.0)) for r in rows)
        for p in pairs:
            p["variant"] = pair_variant(p, base)
            p["scan"] = name
            p["scan_wall"] = wall
        table += pairs
    print("| τ_d/τ_min | variant | s per L | s per second | window (ms) | fit pts | "
          "mode spread | fate +ε | fate −ε | wall of pair (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for p in table:
        print(f"| {p['tau_d_ratio']:.4g} | {p['variant']} (Δx {float(p['dx']) * 1e3:g} mm, "
              f"ε {p['eps']:g}) | {p['s_per_L']:.3g} ± {p['s_per_L_err']:.2g} | "
              f"{p['s_per_s']:.4g} ± {p['s_per_s_err']:.2g} | "
              f"{1e3 * p['t0']:.3g}–{1e3 * p['t1']:.3g} | {p['n']} | {p['mode_spread']:.2g} | "
              f"{p['fate_plus']} | {p['fate_minus']} | {p['wall_time']:.0f} |")
    # agreement with the base pair of each τ_d
    print()
    for name in SCANS:
        sel = [p for p in table if p["scan"] == name]
        if len(sel) < 2:
            continue
        b = sel[0]["s_per_L"]
        dev = {p["variant"]: (p["s_per_L"] / b - 1) for p in sel[1:]}
        print(f"{name}: s = {b:.4g}/L (base); relative changes: "
              + ", ".join(f"{k}: {v:+.1%}" for k, v in dev.items()))
    # how closely the runs of each base pair follow the steady line c_p⁰(L)
    from slippulse.timedomain.perturbation import line_deviation, read_series, smoothed_c_p, steady_curve
    curve = steady_curve(*[f for f in (FAMILY, UPPER) if os.path.exists(f)])
    print("\n| τ_d/τ_min | run | fate | L range (m) | c_p/c_s range | median of abs(c_p/c_p⁰(L) − 1) | "
          "max | fraction of samples in the line's L range |")
    print("|---|---|---|---|---|---|---|---|")
    for name in SCANS:
        sel = [p for p in table if p["scan"] == name]
        if not sel:
            continue
        for tag, key in (("+ε", "_file_plus"), ("−ε", "_file_minus")):
            for p in sel[:1] + [q for q in sel if q["variant"].startswith("ε = ") and
                                q["eps"] >= 0.01 - 1e-12]:
                s = read_series(p[key])
                cs = float(s["attrs"]["c_p"]) / float(s["attrs"]["beta"])
                cp = smoothed_c_p(s)
                keep = (s["distance"] >= 0.1) & (np.arange(cp.size) >= 2) & \
                    (np.arange(cp.size) < cp.size - 2)
                dev = line_deviation(s["L"][keep], cp[keep], curve)
                ok = np.isfinite(dev)
                print(f"| {p['tau_d_ratio']:.4g} | {tag}, ε = {p['eps']:g} | "
                      f"{p['fate_plus' if tag == '+ε' else 'fate_minus']} | "
                      f"{s['L'][keep].min():.3g}–{s['L'][keep].max():.3g} | "
                      f"{cp[keep].min() / cs:.3g}–{cp[keep].max() / cs:.3g} | "
                      f"{np.median(np.abs(dev[ok])) if ok.any() else math.nan:.2g} | "
                      f"{np.max(np.abs(dev[ok])) if ok.any() else math.nan:.2g} | "
                      f"{ok.mean():.2f} |")
    os.makedirs(FIG_DIR, exist_ok=True)
    paths = stability_figures(all_rows, table, FIG_DIR, prefix="stability_",
                              extra_steady=(UPPER,) if os.path.exists(UPPER) else ())
    paths.append(growth_figure(table))
    print("figures:", ", ".join(paths))


def growth_figure(table):
    from matplotlib.figure import Figure
    fig = Figure(figsize=(6.4, 4.0))
    ax, bx = fig.subplots(1, 2)
    for p in table:
        if not math.isfinite(p["s_per_L"]):
            continue
        m = "o" if p["variant"] == "base" else "."
        ax.errorbar(p["tau_d_ratio"], p["s_per_L"], yerr=p["s_per_L_err"], fmt=m, ms=5,
                    color="k" if p["variant"] == "base" else "C1")
        bx.errorbar(p["tau_d_ratio"], p["s_per_s"], yerr=p["s_per_s_err"], fmt=m, ms=5,
                    color="k" if p["variant"] == "base" else "C1")
    ax.axhline(0, color="0.6", lw=0.8)
    bx.axhline(0, color="0.6", lw=0.8)
    ax.set_xlabel("τ_d/τ_min")
    ax.set_ylabel("growth rate s·L/c_p (per pulse length)")
    bx.set_xlabel("τ_d/τ_min")
    bx.set_ylabel("growth rate s (1/s)")
    ax.plot([], [], "ko", label="base pair")
    ax.plot([], [], ".", color="C1", label="refined / other ε, domain, history")
    ax.legend(fontsize=7)
    fig.tight_layout()
    out = os.path.join(FIG_DIR, "stability_growth.png")
    fig.savefig(out, dpi=130)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=("family", "report"))
    a = ap.parse_args()
    if a.what == "family":
        family()
    else:
        report()
    return 0


if __name__ == "__main__":
    sys.exit(main())
