"""The divergence law of the deep family: fits, fit-window study, edge structure, figures.

    python steady/divergence.py FAMILY.h5 [--deep runs/deep] [--outdir docs/figures]
        [--compare DIR_N DIR_2N] [--table TABLE.csv ...]

Reads the converged pulses of a family file and the arclength steps of `steady/deep_march.py`
(DEEP/arc_*.npz, with their grid checks) — or, with no npz there, the deep pulses that
`slippulse steady family` wrote into the file itself (``continuation = "arclength"``) — then
prints, as Markdown:

1. the pulses of the deep march (τ_d, β, L, N, grid-check differences);
2. the fit-window study: the power laws L = A d^−m_L, 1 − β = B d^m_β, d = τ_d/τ_min − τ̃*
   (:func:`slippulse.steady.analysis.divergence_fit`, joint and single), the paper's Eqs. 3–4 fitted for
   (τ̃*, a_v, a_G) (:func:`~slippulse.steady.analysis.scaling_fit`), and the τ̃*-free form in 1 − β
   (:func:`~slippulse.steady.analysis.beta_parametrised_fit`), over windows in τ_d and in L;
3. local exponents d ln L/d ln(1−β) and d ln(q − τ̃*)/d ln(1−β) along the family, and over the
   deepest decade of L: d ln(1−β)/d ln L, d ln L/d ln d with τ̃* from the joint fit to that
   decade, and −dτ_d/d ln L;
4. the paper's Eqs. 3–4 (τ̃* = 1.0087, a_v = 1.15, a_G = 0.69) evaluated on the same pulses;
5. edge structure against L (:func:`~slippulse.steady.analysis.edge_structure`, Ḡ at fixed δ) and the
   distance of each edge profile from that of the longest pulse.

6. with --compare: two marches from the same pulse at N and 2N − 1 (`deep_march.py` without and
   with --refine) compared at equal β (interpolated in ln(1 − β)), the differences converted to
   fixed τ_d along the family, the Richardson extrapolation (order 2) of q and ln L at fixed β,
   and the fits repeated on the N, 2N − 1 and extrapolated branches.

With --table (the tables `steady/deep_seed.py --table` writes beside a committed seed, e.g.
steady/seeds/deep_family_*.csv), their converged, grid-checked rows join the fits and the local
exponents as (τ_d/τ_min, β, L) points (a pulse the family file also holds is taken from the file);
the edge structure is measured on the file's pulses only (a table has no profiles). So a march
chained through seeds is analysed as one family.

Figures (PNG): divergence_deep.png (L and 1 − β against τ_d/τ_min − τ̃* on log axes),
local_exponents_deep.png (the local exponents against L, with τ̃* from the deepest decade of L),
edges_deep.png (edge measures against L), edge_profiles.png (the two edges overlaid).
About 1 min.
"""
import argparse
import glob
import math
import os
import sys

import numpy as np
from matplotlib.figure import Figure

from slippulse.steady import analysis as an
from slippulse.core.h5io import Pulse, list_pulses, read_pulse
from slippulse.core.params import DEFAULT
from slippulse.plotting.steady import PAPER_SCALING
from slippulse.steady.equations import SteadyProblem

Q_WINDOWS = ((1.0, 1.0113), (1.0, 1.0125), (1.0, 1.015), (1.0, 1.02), (1.0, 1.03))
L_MIN = (100.0, 200.0, 400.0, 1000.0, 2000.0)


def load(family, deep_dir):
    """Family-file pulses above the march's first step and the deep-march steps as Pulse objects,
    sorted by decreasing τ_d; steps carry their grid check in ``extra`` (dbeta, dL_rel,
    n_check)."""
    P = DEFAULT
    out = []
    for lab in list_pulses(family):
        pu, _ = read_pulse(family, lab)
        if pu.converged:
            if pu.extra.get("continuation") == "arclength":
                # a deep pulse of `slippulse steady family`: the march step, checked
                pu.extra.update(source=lab, dbeta=float(pu.extra["grid_check_dbeta"]),
                                dL_rel=float(pu.extra["grid_check_dL_rel"]),
                                n_check=float(pu.extra["grid_check_n"]))
            out.append(pu)
    q_last = min(p.tau_d_ratio for p in out)
    for fn in sorted(glob.glob(os.path.join(deep_dir, "arc_*.npz"))):
        z = np.load(fn)
        xi, x = z["xi"], z["x"]
        prob = SteadyProblem(P, float(x[-1]), xi, int(z["pin_index"]), float(z["y_pin"]),
                             free="both",
                             state_order=int(z["state_order"]) if "state_order" in z else 2)
        v, phi, tau, _ = prob.fields(x)
        res = prob.residual(x)[:-1]
        extra = {"source": os.path.basename(fn)}
        for key in ("dbeta", "dL_rel", "n_check"):
            extra[key] = float(z[key]) if key in z else float("nan")
        out.append(Pulse(xi=xi, v=v, phi=phi, tau=tau, residual=res, tau_d_ratio=float(x[-1]),
                         tau_d=prob.tau_d, tau_min=P.tau_min, beta=float(x[-2]),
                         c_p=float(x[-2]) * P.c_s, L=float(z["L"]), L_tilde=float(z["L"]) / P.L_Gc,
                         v_stick=prob.v_stick, v_max=float(v.max()),
                         max_residual=float(np.abs(res).max()), converged=True,
                         n_points=xi.size, wall_time=0.0, extra=extra))
    # the march starts at one of the family's pulses: the family above its first step, the march
    # below
    arc = [p for p in out if "source" in p.extra]
    q_first = max((p.tau_d_ratio for p in arc), default=q_last)
    fam = [p for p in out if "source" not in p.extra and p.tau_d_ratio > q_first]
    return sorted(fam + arc, key=lambda p: -p.tau_d_ratio)


class TableRow:
    """A pulse known by its table row only: τ_d/τ_min, β, L, N and its grid check."""

    xi = None

    def __init__(self, row):
        self.tau_d_ratio, self.beta, self.L = (float(row[k]) for k in ("tau_d_ratio", "beta", "L"))
        self.n_points = int(row["n_points"])
        self.extra = {}
        if row["continuation"] == "arclength":
            self.extra = dict(source=row["label"], dbeta=float(row["grid_check_dbeta"]),
                              dL_rel=float(row["grid_check_dL_rel"]),
                              n_check=float(row["grid_check_n"] or "nan"))


def load_tables(tables, pulses):
    """``pulses`` with the checked rows of the CSV ``tables`` (those at a τ_d/τ_min no pulse
    already has, to 1e−11), sorted by decreasing τ_d."""
    import csv

    out = list(pulses)
    for fn in tables:
        with open(fn, newline="") as fh:
            for row in csv.DictReader(fh):
                q = float(row["tau_d_ratio"])
                if (row["grid_check_passed"] != "True"
                        or any(abs(p.tau_d_ratio - q) < 1e-11 for p in out)):
                    continue
                out.append(TableRow(row))
    return sorted(out, key=lambda p: -p.tau_d_ratio)


def load_march(d):
    """(q, β, L) of the steps of one deep march, in march order."""
    rows = []
    for fn in sorted(glob.glob(os.path.join(d, "arc_*.npz"))):
        z = np.load(fn)
        rows.append((float(z["x"][-1]), float(z["x"][-2]), float(z["L"])))
    return np.array(rows).T


def march_points(d):
    """Grid sizes N of the steps of one deep march (sorted, unique)."""
    return sorted({int(np.load(fn)["xi"].size) for fn in glob.glob(os.path.join(d, "arc_*.npz"))})


def _n_text(ns):
    """'2000' or '2000–3999' for a collection of grid sizes."""
    ns = sorted({int(n) for n in ns})
    if not ns:
        return "?"
    return f"{ns[0]}" if ns[0] == ns[-1] else f"{ns[0]}–{ns[-1]}"


def compare_marches(dir_a, dir_b):
    """Print the N vs 2N − 1 comparison of two marches; return the extrapolated branch."""
    qa, ba, La = load_march(dir_a)
    qb, bb, Lb = load_march(dir_b)
    sa = np.argsort(np.log(1 - ba))
    xa = np.log(1 - ba)[sa]
    xb = np.log(1 - bb)
    inside = (xb >= xa.min()) & (xb <= xa.max())
    qa_b = np.interp(xb, xa, qa[sa])
    lLa_b = np.interp(xb, xa, np.log(La)[sa])
    dq = qb - qa_b                       # at fixed β
    dlnL = np.log(Lb) - lLa_b
    # along the fine branch: dq/dβ and d ln L/dβ, to convert to fixed τ_d
    dqdb = np.gradient(qb, bb)
    dlLdb = np.gradient(np.log(Lb), bb)
    dbeta_q = -dq / dqdb
    dlnL_q = dlnL + dlLdb * dbeta_q
    print(f"\n## N = {_n_text(march_points(dir_a))} against N = {_n_text(march_points(dir_b))} "
          "(nested start) along the branch\n")
    print("| step | β | τ_d/τ_min (2N−1) | L (m, 2N−1) | Δq at fixed β | ΔL/L at fixed β "
          "| Δβ at fixed τ_d | ΔL/L at fixed τ_d | q extrapolated | L extrapolated (m) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    qr = qb + dq / 3.0
    Lr = Lb * np.exp(dlnL / 3.0)
    for k in np.nonzero(inside)[0]:
        print(f"| {k + 1} | {bb[k]:.7f} | {qb[k]:.7f} | {Lb[k]:.5g} | {dq[k]:+.2e} "
              f"| {dlnL[k]:+.2e} | {dbeta_q[k]:+.2e} | {dlnL_q[k]:+.2e} | {qr[k]:.7f} "
              f"| {Lr[k]:.5g} |")
    return {"N": (qa, ba, La), "2N-1": (qb, bb, Lb), "extrapolated": (qr[inside], bb[inside],
                                                                     Lr[inside])}


def _local_m(lnL, q, tau_star):
    """Centred local exponent d ln L/d ln(q − τ̃*) at the inner points of pulses sorted by L
    (NaN where a neighbour lies at or below τ̃*)."""
    d = q - tau_star
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where((d[2:] > 0) & (d[:-2] > 0),
                        -(lnL[2:] - lnL[:-2]) / np.log(np.abs(d[2:] / d[:-2])), np.nan)


def fit_row(name, f):
    return (f"| {name} | {f['n']} | {f['tau_star']:.5f} ± {f['tau_star_err']:.5f}"
            f"{' (at bound)' if f.get('at_bound') else ''} | {f['m_L']:.3f} ± {f['m_L_err']:.3f} "
            f"| {f['m_beta']:.3f} ± {f['m_beta_err']:.3f} | {f['rms']:.1e} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family")
    ap.add_argument("--deep", default=os.path.join("runs", "deep"))
    ap.add_argument("--outdir", default=os.path.join("docs", "figures"))
    ap.add_argument("--compare", nargs=2, default=None, metavar=("DIR_N", "DIR_2N"))
    ap.add_argument("--table", nargs="+", default=[], metavar="CSV",
                    help="tables of checked pulses (steady/deep_seed.py --table) to join")
    a = ap.parse_args(argv)
    P = DEFAULT
    pulses = load_tables(a.table, load(a.family, a.deep))
    q = np.array([p.tau_d_ratio for p in pulses])
    b = np.array([p.beta for p in pulses])
    L = np.array([p.L for p in pulses])
    N = np.array([p.n_points for p in pulses])
    print(f"{len(pulses)} pulses; deepest tau_d/tau_min={q.min():.7f} (beta={b[q.argmin()]:.7f}, "
          f"L={L[q.argmin()]:.5g} m)")

    print("\n## Deep march pulses\n")
    print("| step | N | τ_d/τ_min | β | 1 − β | L (m) | check N | Δβ (N→2N−1) | ΔL/L |")
    print("|---|---|---|---|---|---|---|---|---|")
    for p in pulses:
        if "source" in p.extra:
            e = p.extra
            print(f"| {e['source']} | {p.n_points} | {p.tau_d_ratio:.7f} | {p.beta:.7f} "
                  f"| {1 - p.beta:.3e} | {p.L:.5g} | {int(e['n_check']) or '–'} "
                  f"| {e['dbeta']:.1e} | {e['dL_rel']:.1e} |")

    print("\n## Fit-window study\n")
    print("Power laws, d = τ_d/τ_min − τ̃* (joint fit, then L alone and 1 − β alone):\n")
    print("| window | n | τ̃* | m_L | m_β | rms |")
    print("|---|---|---|---|---|---|")
    fits = {}
    windows = [("q in [%.4f, %.4f]" % w, (q >= w[0]) & (q <= w[1])) for w in Q_WINDOWS]
    windows += [("L ≥ %g m" % lm, L >= lm) for lm in L_MIN]
    for name, sel in windows:
        for quant in ("both", "L", "beta"):
            try:
                f = an.divergence_fit(q[sel], b[sel], L[sel], window=(0.0, 2.0), quantities=quant)
            except ValueError as exc:
                print(f"| {name} ({quant}) | {int(sel.sum())} | {exc} | | | |")
                continue
            fits[(name, quant)] = f
            print(fit_row(f"{name} ({quant})", f))
    print("\nThe paper's Eqs. 3–4 fitted for (τ̃*, a_v, a_G) (paper: 1.0087, 1.15, 0.69):\n")
    print("| window | n | τ̃* | a_v | a_G | rms |")
    print("|---|---|---|---|---|---|")
    for name, sel in windows:
        try:
            f = an.scaling_fit(q[sel], b[sel], L[sel] / P.L_Gc, P, window=(0.0, 2.0))
        except ValueError as exc:
            print(f"| {name} | {int(sel.sum())} | {exc} | | | |")
            continue
        print(f"| {name} | {f['n']} | {f['tau_star']:.5f} ± {f['tau_star_err']:.5f} "
              f"| {f['a_v']:.3f} ± {f['a_v_err']:.3f} | {f['a_G']:.3f} ± {f['a_G_err']:.3f} "
              f"| {f['rms']:.1e} |")
    print("\nτ̃*-free form: q = τ̃* + B(1−β)^p, L = A(1−β)^(−r) (paper asymptotically: p = 1/2, "
          "r = 1/2):\n")
    print("| 1 − β ≤ | n | τ̃* | p | r |")
    print("|---|---|---|---|---|")
    for bmax in (0.05, 0.02, 0.01, 0.005, 0.003):
        try:
            f = an.beta_parametrised_fit(q, b, L, max_one_minus_beta=bmax)
        except ValueError:
            continue
        print(f"| {bmax} | {f['n']} | {f['tau_star']:.5f} ± {f['tau_star_err']:.5f} "
              f"| {f['p']:.3f} ± {f['p_err']:.3f} | {f['r']:.3f} ± {f['r_err']:.3f} |")

    print("\n## Local exponents along the family\n")
    print("| τ_d/τ_min | 1 − β | L (m) | d ln L/d ln(1−β) | d ln L/d ln d (τ̃* = 1.0087) |")
    print("|---|---|---|---|---|")
    om = 1 - b
    for i in range(1, len(pulses) - 1):
        if om[i] > 0.03 or i % max(1, len(pulses) // 40):
            continue
        j, k = i - 1, i + 1
        r_loc = -(math.log(L[k]) - math.log(L[j])) / (math.log(om[k]) - math.log(om[j]))
        d = q - PAPER_SCALING["tau_star"]
        m_loc = (-(math.log(L[k]) - math.log(L[j])) / (math.log(d[k]) - math.log(d[j]))
                 if d[k] > 0 and d[j] > 0 else float("nan"))
        print(f"| {q[i]:.6f} | {om[i]:.3e} | {L[i]:.4g} | {r_loc:.3f} | {m_loc:.3f} |")

    # the deepest decade of L: local exponents against L, with τ̃* from the
    # joint fit to that decade, and the two single fits that bracket it
    deep = L >= L.max() / 10.0
    tau_deep, loc = float("nan"), None
    if deep.sum() >= 6:
        fd = {qt: an.divergence_fit(q[deep], b[deep], L[deep], window=(0.0, 2.0), quantities=qt)
              for qt in ("both", "L", "beta")}
        tau_deep = fd["both"]["tau_star"]
        print(f"\n## The deepest decade of L ({L[deep].min():.4g}–{L.max():.4g} m, "
              f"{int(deep.sum())} pulses)\n")
        print(f"τ̃* = {tau_deep:.5f} ± {fd['both']['tau_star_err']:.5f} (joint), "
              f"{fd['L']['tau_star']:.5f} (L alone), {fd['beta']['tau_star']:.5f} (1 − β alone); "
              "local exponents (centred differences):\n")
        print("| L (m) | τ_d/τ_min | d ln L/d ln(1−β) | d ln(1−β)/d ln L "
              f"| d ln L/d ln d (τ̃* = {tau_deep:.5f}) | −dτ_d/d ln L |")
        print("|---|---|---|---|---|---|")
        order = np.argsort(L)
        lnL, lnb, qq = np.log(L[order]), np.log(1 - b[order]), q[order]
        loc = dict(L=L[order][1:-1],
                   r=((lnL[2:] - lnL[:-2]) / (lnb[2:] - lnb[:-2])),
                   m=_local_m(lnL, qq, tau_deep),
                   s=-(qq[2:] - qq[:-2]) / (lnL[2:] - lnL[:-2]))
        last = -1.0
        for k in range(loc["L"].size):
            if loc["L"][k] >= L.max() / 10.0 and loc["L"][k] >= 1.15 * last:
                last = loc["L"][k]
                print(f"| {loc['L'][k]:.4g} | {qq[k + 1]:.7f} | {-loc['r'][k]:.3f} "
                      f"| {-1.0 / loc['r'][k]:.4f} | {loc['m'][k]:.3f} | {loc['s'][k]:.2e} |")

    if a.compare:
        branches = compare_marches(*a.compare)
        print("\nFits on the three branches (steps from τ_d/τ_min ≈ 1.0123 down):\n")
        print("| branch | fit | n | τ̃* | exponents / constants | rms |")
        print("|---|---|---|---|---|---|")
        for name, (qq, bb_, LL) in branches.items():
            for lo in (0.0, 300.0):
                sel = LL >= lo
                tag = f"{name}, L ≥ {lo:g} m"
                try:
                    f = an.divergence_fit(qq[sel], bb_[sel], LL[sel], window=(0.0, 2.0))
                    print(f"| {tag} | power laws (joint) | {f['n']} | {f['tau_star']:.5f} ± "
                          f"{f['tau_star_err']:.5f} | m_L = {f['m_L']:.3f} ± {f['m_L_err']:.3f}, "
                          f"m_β = {f['m_beta']:.3f} ± {f['m_beta_err']:.3f} | {f['rms']:.1e} |")
                    f = an.scaling_fit(qq[sel], bb_[sel], LL[sel] / P.L_Gc, P, window=(0.0, 2.0))
                    print(f"| {tag} | Eqs. 3–4 | {f['n']} | {f['tau_star']:.5f} ± "
                          f"{f['tau_star_err']:.5f} | a_v = {f['a_v']:.3f} ± {f['a_v_err']:.3f}, "
                          f"a_G = {f['a_G']:.3f} ± {f['a_G_err']:.3f} | {f['rms']:.1e} |")
                    f = an.beta_parametrised_fit(qq[sel], bb_[sel], LL[sel], 1.0)
                    print(f"| {tag} | q = τ̃* + B(1−β)^p, L ∝ (1−β)^−r | {f['n']} "
                          f"| {f['tau_star']:.5f} ± {f['tau_star_err']:.5f} | p = {f['p']:.3f} ± "
                          f"{f['p_err']:.3f}, r = {f['r']:.3f} ± {f['r_err']:.3f} | |")
                except ValueError as exc:
                    print(f"| {tag} | – | {int(sel.sum())} | {exc} | | |")

    print("\n## The paper's Eqs. 3–4 on the same pulses\n")
    bm, Ltm = an.scaling_law(q, PAPER_SCALING["tau_star"], PAPER_SCALING["a_v"],
                             PAPER_SCALING["a_G"], P)
    print("| τ_d/τ_min | N | β | β (paper) | 1−β | 1−β (paper) | L (m) | L (paper, m) |")
    print("|---|---|---|---|---|---|---|---|")
    idx = np.nonzero(q < 1.03)[0]
    for i in idx[np.unique(np.linspace(0, idx.size - 1, 14).astype(int))]:
        print(f"| {q[i]:.6f} | {N[i]} | {b[i]:.6f} | {bm[i]:.6f} | {1 - b[i]:.3e} "
              f"| {1 - bm[i]:.3e} | {L[i]:.4g} | {Ltm[i] * P.L_Gc:.4g} |")

    print("\n## Edge structure against L\n")
    profiled = [p for p in pulses if p.xi is not None]
    tau_m = min(p.tau.min() for p in profiled)
    rows = []
    for p in sorted(profiled, key=lambda p: p.L):
        if p.tau_d_ratio >= 1.06 or (rows and p.L < 1.1 * rows[-1][1]["L"]):
            continue
        e = an.edge_structure(p.xi, p.v, p.tau, P.v_star, p.v_stick)
        delta, G = an.breakdown_energy(p.xi, p.v, p.tau, p.v_stick, p.beta, P.c_s, tau_m)
        order = np.argsort(delta)
        e["G"] = [float(np.interp(dd, delta[order], G[order])) for dd in (2e-6, 5e-6, 2e-5)]
        e["G_max"] = float(G.max())
        rows.append((p, e))
    ref_p, ref_e = rows[-1]
    print("| τ_d/τ_min | N | L (m) | √(1−β²) | v_max√(1−β²) (m/s) | τ_max/τ_min | ℓ/√(1−β²) (mm) "
          "| front e-fold/√(1−β²) (mm) | back e-fold (m) | τ_back,min/τ_min | healing width (m) "
          "| Ḡ(2 µm) | Ḡ(5 µm) | Ḡ(20 µm) (J/m²) | Ḡ_max | front dist. | back dist. |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for p, e in rows:
        g = math.sqrt(1 - p.beta ** 2)
        gr = math.sqrt(1 - ref_p.beta ** 2)
        # profiles relative to their edges, the front in Lorentz-contracted units (ξ/√(1−β²))
        df = an.profile_distance(p.xi / g, np.log(p.v * g), e["x_front"] / g, ref_p.xi / gr,
                                 np.log(ref_p.v * gr), ref_e["x_front"] / gr, 0.03)
        db = an.profile_distance(p.xi, np.log(p.v), e["x_back"], ref_p.xi, np.log(ref_p.v),
                                 ref_e["x_back"], 5.0)
        e["front_dist"], e["back_dist"] = df, db
        print(f"| {p.tau_d_ratio:.5f} | {p.n_points} | {p.L:.4g} | {g:.4f} | {e['v_max'] * g:.4f} "
              f"| {e['tau_max'] / P.tau_min:.5f} | {1e3 * e['ell'] / g:.4g} "
              f"| {1e3 * e['front_efold'] / g:.4g} | {e['back_efold']:.4g} "
              f"| {e['tau_back_min'] / P.tau_min:.5f} | {e['heal_width']:.4g} "
              f"| {e['G'][0]:.4g} | {e['G'][1]:.4g} | {e['G'][2]:.4g} | {e['G_max']:.4g} "
              f"| {df:.3f} | {db:.3f} |")
    print(f"\n(front dist.: max |Δ ln(v√(1−β²))| against the longest pulse (L = {ref_p.L:.4g} m) "
          "over ±30 mm·√(1−β²) about the steepest point of the leading edge; back dist.: "
          "max |Δ ln v| over ±5 m about the steepest point of the healing front)")

    os.makedirs(a.outdir, exist_ok=True)
    f = fits.get(("L ≥ 100 m", "both")) or fits.get(("q in [1.0000, 1.0125]", "both"))
    if f is not None:
        fig = Figure(figsize=(9, 4))
        ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
        arc = np.array(["source" in p.extra for p in pulses])
        for sel, mk, lab in ((~arc, "o", f"family (τ_d- and β-steps), N = {_n_text(N[~arc])}"),
                             (arc, "s", f"arclength march (deformed grid), N = {_n_text(N[arc])}")):
            s_ = sel & (q - f["tau_star"] > 0) & (q < 1.05)
            d = q[s_] - f["tau_star"]
            ax1.loglog(d, L[s_], mk, ms=3, mfc="none", label=lab)
            ax2.loglog(d, 1 - b[s_], mk, ms=3, mfc="none", label=lab)
        if a.compare:
            qr, br, Lr = branches["extrapolated"]
            s_ = qr - f["tau_star"] > 0
            ax1.loglog(qr[s_] - f["tau_star"], Lr[s_], "k+", ms=5,
                       label=f"extrapolated N → ∞ (Richardson, N = "
                             f"{_n_text(march_points(a.compare[0]))} and "
                             f"{_n_text(march_points(a.compare[1]))})")
            ax2.loglog(qr[s_] - f["tau_star"], 1 - br[s_], "k+", ms=5, label="extrapolated")
        dd = np.geomspace(0.5 * (q.min() - f["tau_star"]), 0.04, 100)
        ax1.loglog(dd, np.exp(f["ln_A"]) * dd ** (-f["m_L"]), "k-",
                   label=f"fit L ≥ 100 m: m_L = {f['m_L']:.2f}, τ̃* = {f['tau_star']:.5f}")
        ax2.loglog(dd, np.exp(f["ln_B"]) * dd ** f["m_beta"], "k-",
                   label=f"fit: m_β = {f['m_beta']:.2f}")
        xx = PAPER_SCALING["tau_star"] + np.geomspace(1e-5, 0.04, 200)
        bp, Lp = an.scaling_law(xx, PAPER_SCALING["tau_star"], PAPER_SCALING["a_v"],
                                PAPER_SCALING["a_G"], P)
        ok = xx - f["tau_star"] > 0
        ax1.loglog(xx[ok] - f["tau_star"], Lp[ok] * P.L_Gc, "r--",
                   label="paper Eqs. 3–4 (τ̃* = 1.0087)")
        ax2.loglog(xx[ok] - f["tau_star"], 1 - bp[ok], "r--", label="paper Eqs. 3–4")
        ax1.set_xlabel("τ_d/τ_min − τ̃*"), ax1.set_ylabel("L (m)")
        ax2.set_xlabel("τ_d/τ_min − τ̃*"), ax2.set_ylabel("1 − β")
        ax1.legend(fontsize=7), ax2.legend(fontsize=7)
        fig.suptitle(f"L and 1 − β against τ_d/τ_min − τ̃*, τ̃* = {f['tau_star']:.5f} from the "
                     "joint fit to the pulses with L ≥ 100 m", fontsize=9)
        fig.tight_layout()
        fig.savefig(os.path.join(a.outdir, "divergence_deep.png"), dpi=130)
    if loc is not None:
        fig = Figure(figsize=(9, 3.6))
        ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
        ok = loc["L"] >= 30.0
        ax1.semilogx(loc["L"][ok], -loc["r"][ok], "o", ms=3, mfc="none",
                     label="d ln L/d ln(1 − β)")
        ax1.semilogx(loc["L"][ok], -1.0 / loc["r"][ok], "s", ms=3, mfc="none",
                     label="d ln(1 − β)/d ln L")
        ax1.axhline(0.5, color="C0", ls="--", lw=1, label="paper's asymptote of d ln L/d ln(1 − β): 1/2")
        ax1.axhline(2.0, color="C1", ls="--", lw=1, label="and of d ln(1 − β)/d ln L: 2")
        ax1.set_xlabel("L (m)"), ax1.set_ylabel("local exponent"), ax1.legend(fontsize=7)
        ax2.semilogx(loc["L"][ok], loc["m"][ok], "o", ms=3, mfc="none",
                     label=f"τ̃* = {tau_deep:.5f} (joint fit, deepest decade)")
        mp = _local_m(np.log(np.sort(L)), q[np.argsort(L)], PAPER_SCALING["tau_star"])
        ax2.semilogx(loc["L"][ok], mp[ok], "^", ms=3, mfc="none", color="r",
                     label="τ̃* = 1.0087 (paper)")
        ax2.axhline(1.0, color="r", ls="--", lw=1, label="paper's asymptote m_L = 1")
        ax2.set_xlabel("L (m)"), ax2.set_ylabel("d ln L/d ln(τ_d/τ_min − τ̃*)")
        ax2.legend(fontsize=7)
        fig.suptitle(f"Local exponents along the family (deepest pulse L = {L.max():.4g} m at "
                     f"τ_d/τ_min = {q.min():.6f})", fontsize=9)
        fig.tight_layout()
        fig.savefig(os.path.join(a.outdir, "local_exponents_deep.png"), dpi=130)
    fig = Figure(figsize=(11, 3.4))
    axs = [fig.add_subplot(1, 3, k) for k in (1, 2, 3)]
    Ls = np.array([e["L"] for _, e in rows])
    gs = np.array([math.sqrt(1 - p.beta ** 2) for p, _ in rows])
    axs[0].loglog(Ls, 1e3 * np.array([e["ell"] for _, e in rows]) / gs, "o-",
                  label="ℓ/√(1−β²) (mm)")
    axs[0].loglog(Ls, 1e3 * np.array([e["front_efold"] for _, e in rows]) / gs, "s-",
                  label="front e-fold/√(1−β²) (mm)")
    axs[0].loglog(Ls, [e["back_efold"] for _, e in rows], "v-", label="back e-fold (m)")
    axs[0].loglog(Ls, [e["heal_width"] for _, e in rows], "^-", label="healing width (m)")
    axs[0].legend(fontsize=7), axs[0].set_xlabel("L (m)")
    axs[1].semilogx(Ls, [e["tau_max"] / P.tau_min for _, e in rows], "o-", label="τ_max/τ_min")
    axs[1].semilogx(Ls, [e["tau_back_min"] / P.tau_min for _, e in rows], "s-",
                    label="τ_back,min/τ_min")
    axs[1].semilogx(Ls, [e["v_max"] * g for (_, e), g in zip(rows, gs)], "^-",
                    label="v_max√(1−β²) (m/s)")
    axs[1].legend(fontsize=7), axs[1].set_xlabel("L (m)")
    for k_, lab in enumerate(("Ḡ(2 µm)", "Ḡ(5 µm)", "Ḡ(20 µm)")):
        axs[2].semilogx(Ls, [e["G"][k_] for _, e in rows], "o-", label=lab)
    axs[2].semilogx(Ls, [e["G_max"] for _, e in rows], "k^-", label="Ḡ_max")
    axs[2].set_yscale("log"), axs[2].legend(fontsize=7), axs[2].set_xlabel("L (m)")
    axs[2].set_ylabel("J/m²")
    fig.tight_layout()
    fig.savefig(os.path.join(a.outdir, "edges_deep.png"), dpi=130)
    fig = Figure(figsize=(10, 3.6))
    ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    for p, e in rows[::max(1, len(rows) // 8)] + [rows[-1]]:
        g = math.sqrt(1 - p.beta ** 2)
        s1 = np.abs(p.xi - e["x_front"]) < 0.1 * g
        ax1.plot(1e3 * (p.xi[s1] - e["x_front"]) / g, np.log10(p.v[s1] * g), "-",
                 label=f"L = {p.L:.3g} m")
        s2 = np.abs(p.xi - e["x_back"]) < 10.0
        ax2.plot(p.xi[s2] - e["x_back"], np.log10(p.v[s2]), "-", label=f"L = {p.L:.3g} m")
    ax1.set_xlabel("(ξ − ξ_front)/√(1−β²) (mm)"), ax1.set_ylabel("log10(v√(1−β²)) (m/s)")
    ax1.set_title("leading edge", fontsize=9)
    ax2.set_xlabel("ξ − ξ_back (m)"), ax2.set_ylabel("log10 v (m/s)")
    ax2.set_title("healing front", fontsize=9)
    ax1.legend(fontsize=6), ax2.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(os.path.join(a.outdir, "edge_profiles.png"), dpi=130)
    return 0


if __name__ == "__main__":
    sys.exit(main())
