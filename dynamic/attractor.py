"""The attractor claim mode by mode (docs/stability.md §4).

    python dynamic/attractor.py overlap FAMILY.h5 [--csv OUT.csv] [--figure PNG] [--sbi SCAN_DIR ...]
    python dynamic/attractor.py pairs SCAN_DIR ...

``overlap``: at every pulse of the family file with a stored spectrum (``slippulse steady
stability FAMILY.h5``), the overlap of the unstable eigenmode with the family tangent d(y, ln φ)/dτ_d,
both in the frame of the front (``eigenmode.pulse_overlap``), and the mode's direction in the
(ln L, ln c_p) plane against the steady line's: the predicted departure fraction
f = 1 − (d ln c/d ln L)_line / (d ln c/d ln L)_mode (0: along the line). The figure draws both
against τ_d with the measured departures of the SBI (docs/results.md §3 and the mode-seeded pairs given by --sbi).

``pairs``: for each eigenmode-seeded ±ε pair of a scan directory, the growth rate against the
eigenvalue and the measured front displacement and length change per unit v_max change against
the mode's prediction (``eigenmode.front_response``), i.e. the departure fraction the SBI measures.
"""
from __future__ import annotations

import argparse
import csv
import glob
import math
import os
import sys

import numpy as np

from slippulse.core.h5io import read_pulse
from slippulse.timedomain.eigenmode import family_overlaps, front_response, leading_mode
from slippulse.timedomain.perturbation import read_series

#: docs/results.md §3 (generic ±ε pairs, the whole trajectory to the fate): median of
#: |c_p/c_p⁰(L) − 1| of the + and − runs.
SECTION6 = {1.2: (0.069, 0.28), 1.1: (0.03, 0.021), 1.05: (0.00036, 0.0016)}


def _pairs(scan_dir):
    files = [f for f in sorted(glob.glob(os.path.join(scan_dir, "*.h5")))
             if not os.path.basename(f).startswith("summary")]
    runs = {}
    for f in files:
        s = read_series(f)
        a = s["attrs"]
        if str(a.get("perturbation")) not in ("mode", "mode_front"):
            continue
        # one pair per case: the period and the seed's frame tell pairs of one scan apart
        key = (str(a["steady_file"]), str(a["label"]), float(a["dx"]), abs(float(a["eps"])),
               float(a["ahead"]), float(a["behind"]), str(a["perturbation"]))
        runs.setdefault(key, {})[1 if float(a["eps"]) > 0 else -1] = s
    return [(k, g[1], g[-1]) for k, g in runs.items() if 1 in g and -1 in g]


def pair_analysis(key, plus, minus, d_max=0.03):
    """Rate (fit of ln|r| from the start to the end of the linear regime and over its first
    third), and the amplitude ratios rX/r, rL/r of the antisymmetric front displacement and
    length change per unit antisymmetric v_max change, against the mode's prediction."""
    steady, label, dx, eps = key[:4]
    a = plus["attrs"]
    n = min(plus["t"].size, minus["t"].size)
    t = plus["t"][:n]
    conv = float(a["L"]) / float(a["c_p"])

    def anti(name):
        return 0.5 * (plus[name][:n] - np.interp(t, minus["t"], minus[name]))

    r = anti("v_max_error")
    rX = anti("x_front") if "x_front" in plus else None
    rL = anti("L") / float(a["L"])
    big = np.maximum(np.abs(plus["v_max_error"][:n]),
                     np.abs(np.interp(t, minus["t"], minus["v_max_error"])))
    end = np.nonzero(big > d_max)[0]
    i1 = int(end[0]) if end.size else n
    sel = np.arange(1, i1)
    s_all = np.polyfit(t[sel], np.log(np.abs(r[sel])), 1)[0] * conv
    first = sel[: max(5, sel.size // 3)]
    s_first = np.polyfit(t[first], np.log(np.abs(r[first])), 1)[0] * conv
    # amplitude ratios over the second half of the regime (front position noise is sub-cell)
    late = sel[sel.size // 2:]
    kX = float(np.sum(rX[late] * r[late]) / np.sum(r[late] ** 2)) if rX is not None else math.nan
    kL = float(np.sum(rL[late] * r[late]) / np.sum(r[late] ** 2))
    pulse, params = read_pulse(steady, label)
    mode = leading_mode(pulse, params, path=steady, compute=False)
    fr = front_response(mode, pulse, params.v_star)
    sig = mode.sigma.real
    return {"label": label, "steady": os.path.basename(steady), "dx": dx, "eps": eps,
            "period_L": key[4] + key[5], "perturbation": key[6],
            "eigen_s_per_L": mode.s_per_L, "s_fit_all": s_all, "s_fit_first_third": s_first,
            "d_end": float(t[i1 - 1] / conv),
            "rel_all": s_all / mode.s_per_L - 1, "rel_first": s_first / mode.s_per_L - 1,
            "dc_per_dv_sbi": sig * kX / pulse.c_p,
            "dc_per_dv_mode": fr["dc_over_c"] / fr["dvmax_over_vmax"],
            "dL_per_dv_sbi": kL, "dL_per_dv_mode": fr["dL_over_L"] / fr["dvmax_over_vmax"]}


def cmd_pairs(dirs):
    rows = []
    for d in dirs:
        for key, p, m in _pairs(d):
            rows.append(pair_analysis(key, p, m))
    for r in rows:
        print(" ".join(f"{k}={v:.5g}" if isinstance(v, float) else f"{k}={v}"
                       for k, v in r.items()))
    return rows


def cmd_overlap(path, csv_out=None, figure=None, sbi_dirs=(), local_h=None, labels=None):
    rows = family_overlaps(path, local_h=local_h, labels=labels)
    if not rows:
        sys.exit(f"{path}: no pulse with a stored spectrum and a neighbour")
    keys = ["label", "tau_d_ratio", "s_per_L", "overlap", "overlap_y", "dL_over_L", "dc_over_c",
            "direction", "line_slope", "departure_fraction", "angle_deg"]
    for r in rows:
        print(" ".join(f"{k}={r[k]:.4g}" if isinstance(r[k], float) else f"{k}={r[k]}"
                       for k in keys))
    if csv_out:
        with open(csv_out + ".part", "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
            w.writeheader()
            for r in rows:
                w.writerow({k: (float(r[k]) if k != "label" else r[k]) for k in keys})
        os.replace(csv_out + ".part", csv_out)
    sbi = []
    for d in sbi_dirs:
        for key, p, m in _pairs(d):
            a = pair_analysis(key, p, m)
            pulse, params = read_pulse(key[0], key[1])
            line = [r for r in rows if abs(r["tau_d_ratio"] - pulse.tau_d_ratio) < 1e-9]
            if line and a["dc_per_dv_sbi"]:
                f = 1 - line[0]["line_slope"] * a["dL_per_dv_sbi"] / a["dc_per_dv_sbi"]
                sbi.append((pulse.tau_d_ratio, f))
    if figure:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        q = np.array([r["tau_d_ratio"] for r in rows])
        fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
        ax[0].plot(q, [r["overlap"] for r in rows], "o-", label="y and ln φ")
        ax[0].plot(q, [r["overlap_y"] for r in rows], "s--", ms=4, label="y = ln(v/v*+1) only")
        ax[0].set_xlabel("τ_d/τ_min")
        ax[0].set_ylabel("overlap |⟨mode, tangent⟩|/(‖mode‖‖tangent‖)")
        ax[0].set_title("unstable mode vs family tangent d(y, ln φ)/dτ_d\n(front frame, "
                        "[−1.5, 0.5] L)", fontsize=9)
        ax[0].set_ylim(0, 1.05)
        ax[0].legend(fontsize=8)
        f = np.array([r["departure_fraction"] for r in rows])
        ax[1].plot(q, np.clip(f, -3, 3), "o-", label="eigenmode: 1 − slope_line/slope_mode")
        if sbi:
            sq, sf = zip(*sbi)
            ax[1].plot(sq, sf, "k*", ms=11, label="SBI, eigenmode-seeded ±ε pairs")
        for qq, (mp, mm) in SECTION6.items():
            ax[1].plot([qq, qq], [mp, mm], "rv", ms=6,
                       label="SBI ±ε runs: median |c_p/c_p⁰(L) − 1| (±ε runs)"
                       if qq == 1.2 else None)
        ax[1].axhline(0, color="0.6", lw=0.6)
        ax[1].set_xlabel("τ_d/τ_min")
        ax[1].set_ylabel("departure fraction f (0: along the steady line)")
        ax[1].set_title("c_p/c_p⁰(L) − 1 ≈ f · δ ln c_p in the linear regime", fontsize=9)
        ax[1].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(figure, dpi=110)
        print(f"figure {figure}")
    return rows


def cmd_figure(out, csvs, pair_dirs=(), labels=()):
    """overlap and departure fraction against τ_d from ``overlap --csv`` files (one style each,
    named by ``labels``), with the departure fraction the eigenmode-seeded SBI pairs measure."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.3))
    marks = ["o-", "s-", "^-", "d-"]
    for i, path in enumerate(csvs):
        with open(path) as fh:
            rows = sorted(csv.DictReader(fh), key=lambda r: float(r["tau_d_ratio"]))
        q = np.array([float(r["tau_d_ratio"]) for r in rows])
        lab = labels[i] if i < len(labels) else os.path.basename(path)
        ax[0].plot(q, [float(r["overlap"]) for r in rows], marks[i % 4], ms=5, label=lab)
        f = np.array([float(r["departure_fraction"]) for r in rows])
        ax[1].plot(q, np.clip(f, -1.5, 1.5), marks[i % 4], ms=5, label=f"eigenmode, {lab}")
    sbi = []
    for d in pair_dirs:
        for key, p, m in _pairs(d):
            a = pair_analysis(key, p, m)
            pulse, params = read_pulse(key[0], key[1])
            mode = leading_mode(pulse, params, path=key[0], compute=False)
            from slippulse.timedomain.eigenmode import local_neighbours, pulse_overlap
            ov = pulse_overlap(pulse, mode, local_neighbours(pulse, params), params.v_star)
            f = 1 - ov["line_slope"] * a["dL_per_dv_sbi"] / a["dc_per_dv_sbi"]
            sbi.append((pulse.tau_d_ratio, f))
            print(f"SBI pair {key[1]} ({os.path.basename(key[0])}, eps {key[3]:g}): departure "
                  f"fraction {f:.4g} (mode {ov['departure_fraction']:.4g})")
    if sbi:
        sq, sf = zip(*sbi)
        ax[1].plot(sq, sf, "k*", ms=12, label="SBI, eigenmode-seeded ±ε pairs (measured)")
    ax[0].set_xlabel("τ_d/τ_min")
    ax[0].set_ylabel("overlap |⟨m, t⟩| / (‖m‖ ‖t‖)")
    ax[0].set_ylim(0, 1.05)
    ax[0].set_title("unstable eigenmode m vs family tangent t = d(y, ln φ)/dτ_d\n"
                    "(front frame, translation removed, ζ ∈ [−1.5, 0.5] L)", fontsize=9)
    ax[0].legend(fontsize=8)
    ax[1].axhline(0, color="0.6", lw=0.6)
    ax[1].axhline(1, color="0.8", lw=0.6, ls=":")
    ax[1].set_xlabel("τ_d/τ_min")
    ax[1].set_ylabel("departure fraction f = 1 − slope_line/slope_mode")
    ax[1].set_title("c_p/c_p⁰(L) − 1 ≈ f · δ ln c_p (0: along the steady line;\n"
                    "1: c_p changes at fixed L; > 1: L and c_p move oppositely)", fontsize=9)
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    print(f"figure {out}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    sub = ap.add_subparsers(dest="cmd", required=True)
    o = sub.add_parser("overlap")
    o.add_argument("family")
    o.add_argument("--csv")
    o.add_argument("--figure")
    o.add_argument("--sbi", nargs="*", default=[])
    o.add_argument("--local-h", type=float, default=None,
                   help="tangent from pulses at tau_d +- h solved on each pulse's grid")
    o.add_argument("--labels", nargs="*", default=None)
    fg = sub.add_parser("figure")
    fg.add_argument("out")
    fg.add_argument("--csv", nargs="+", required=True)
    fg.add_argument("--labels", nargs="*", default=[])
    fg.add_argument("--pairs", nargs="*", default=[])
    p = sub.add_parser("pairs")
    p.add_argument("dirs", nargs="+")
    a = ap.parse_args(argv)
    if a.cmd == "overlap":
        cmd_overlap(a.family, a.csv, a.figure, a.sbi, a.local_h, a.labels)
    elif a.cmd == "figure":
        cmd_figure(a.out, a.csv, a.pairs, a.labels)
    else:
        cmd_pairs(a.dirs)


if __name__ == "__main__":
    main()
