"""The divergence law of the deep family: fits, fit-window study, edge structure, figures.

    python steady/divergence.py FAMILY.h5 [--deep runs/deep] [--outdir runs/figures]

Reads the pulses of a family file (τ_d-continuation and β-steps, all N) and the arclength steps
of `steady/deep_march.py` (OUTDIR/arc_N_kkk.npz), then prints, as Markdown:

1. the joint and single power-law fits L = A d^−m_L, 1 − β = B d^m_β, d = τ_d/τ_min − τ̃*
   (:func:`slippulse.steady.analysis.divergence_fit`) over several windows, per grid size N;
2. the paper's Eqs. 3–4 (τ̃* = 1.0087, a_v = 1.15, a_G = 0.69) evaluated on the same pulses;
3. edge structure against L: v_max, τ_max, the leading-edge length ℓ = ξ(τ_max) − ξ(v_max), the
   e-fold length of v ahead of the leading edge, the healing-edge width, Ḡ at fixed δ.

and writes divergence.png/.pdf (L and 1 − β against τ_d/τ_min − τ̃* on log axes) and
edges.png/.pdf. About 1–2 min (recomputes φ and τ of the arclength steps).
"""
import argparse
import glob
import math
import os
import re
import sys

import numpy as np
from matplotlib.figure import Figure
from scipy.optimize import least_squares

from slippulse import analysis as an
from slippulse.core.h5io import Pulse, list_pulses, read_pulse
from slippulse.core.params import DEFAULT
from slippulse.plotting.steady import PAPER_SCALING
from slippulse.steady.equations import SteadyProblem

WINDOWS = ((1.0, 1.0125), (1.0, 1.015), (1.0, 1.02), (1.0, 1.03), (1.0115, 1.02), (1.0125, 1.03))


def load(family, deep_dir):
    """Pulses as Pulse objects (family file) and the arclength steps rebuilt as Pulses."""
    P = DEFAULT
    out = []
    for lab in list_pulses(family):
        pu, _ = read_pulse(family, lab)
        if pu.converged:
            out.append(pu)
    for fn in sorted(glob.glob(os.path.join(deep_dir, "arc_*.npz"))):
        z = np.load(fn)
        xi, x = z["xi"], z["x"]
        prob = SteadyProblem(P, float(x[-1]), xi, int(z["pin_index"]) if "pin_index" in z else 0,
                             0.0, free="both")
        v, phi, tau, _ = prob.fields(x)
        res = prob.residual(x)[:-1]
        L = float(z["L"])
        out.append(Pulse(xi=xi, v=v, phi=phi, tau=tau, residual=res, tau_d_ratio=float(x[-1]),
                         tau_d=prob.tau_d, tau_min=P.tau_min, beta=float(x[-2]),
                         c_p=float(x[-2]) * P.c_s, L=L, L_tilde=L / P.L_Gc, v_stick=prob.v_stick,
                         v_max=float(v.max()), max_residual=float(np.abs(res).max()),
                         converged=True, n_points=xi.size, wall_time=0.0,
                         extra={"source": os.path.basename(fn)}))
    return out


def edge_measures(pu, tau_m):
    """Leading- and healing-edge measures of one pulse (lengths in m)."""
    P = DEFAULT
    xi, v, tau = pu.xi, pu.v, pu.tau
    y = np.log(v / P.v_star + 1.0)
    iv, it = int(np.argmax(v)), int(np.argmax(tau))
    # e-fold length of v − v_stick ahead of the maximum: min over the front of 1/|d ln(v−v_st)/dξ|
    u = np.log(np.maximum(v - pu.v_stick, 1e-300))
    ahead = slice(iv, it + 1)
    g = np.abs(np.gradient(u[ahead], xi[ahead])) if it > iv + 2 else np.array([np.nan])
    efold = float(1.0 / np.nanmax(g))
    # healing edge: distance over which y falls from 90 % to 10 % of its maximum, behind the body
    ymax = y.max()
    L, xl, xr = an.pulse_length(xi, v, P.v_star)
    back = xi < xl + 0.25 * L
    yb, xb = y[back], xi[back]
    order = np.argsort(yb)
    x90 = float(np.interp(0.9 * ymax, yb[order], xb[order]))
    x10 = float(np.interp(0.1 * ymax, yb[order], xb[order]))
    delta, G = an.breakdown_energy(xi, v, tau, pu.v_stick, pu.beta, P.c_s, tau_m)
    order = np.argsort(delta)
    Gd = [float(np.interp(d, delta[order], G[order])) for d in (1e-6, 2e-6, 5e-6)]
    return {"q": pu.tau_d_ratio, "beta": pu.beta, "L": L, "N": pu.n_points,
            "v_max": float(v[iv]), "tau_max": float(tau[it]) / P.tau_min,
            "tau_m": float(tau.min()) / P.tau_min, "ell": float(xi[it] - xi[iv]), "efold": efold,
            "heal_width": x90 - x10, "G1": Gd[0], "G2": Gd[1], "G5": Gd[2],
            "G_max": float(G.max()), "slip": float(delta[0])}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family")
    ap.add_argument("--deep", default=os.path.join("runs", "deep"))
    ap.add_argument("--outdir", default=os.path.join("runs", "figures"))
    a = ap.parse_args(argv)
    P = DEFAULT
    pulses = load(a.family, a.deep)
    q = np.array([p.tau_d_ratio for p in pulses])
    b = np.array([p.beta for p in pulses])
    L = np.array([p.L for p in pulses])
    N = np.array([p.n_points for p in pulses])
    arc = np.array(["source" in p.extra for p in pulses])
    print(f"{len(pulses)} pulses; deepest tau_d/tau_min={q.min():.6f} (beta={b[q.argmin()]:.6f}, "
          f"L={L[q.argmin()]:.4g} m); largest L={L.max():.4g} m")
    sets = {"family file, N = 2000": (N == 2000) & ~arc,
            "family file + arclength steps, N = 2000": N == 2000}
    if np.any(N == 4000):
        q4 = q[N == 4000].max()
        sets["family file (N = 2000) above, arclength N = 4000 below %.4f" % q4] = \
            (N == 4000) | ((N == 2000) & ~arc & (q > q4 + 1e-4))
    print("\n| data | window | n | τ̃* | m_L | m_β | rms | τ̃* (L only) | m_L (L only) | τ̃* (β only) | m_β (β only) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    fits = {}
    for name, sel in sets.items():
        for w in WINDOWS:
            try:
                f = an.divergence_fit(q[sel], b[sel], L[sel], window=w)
                fl = an.divergence_fit(q[sel], b[sel], L[sel], window=w, quantities="L")
                fb = an.divergence_fit(q[sel], b[sel], L[sel], window=w, quantities="beta")
            except ValueError as exc:
                print(f"| {name} | {w} | – | {exc} |")
                continue
            fits[(name, w)] = f
            flag = " (at bound)" if f["at_bound"] else ""
            print(f"| {name} | [{w[0]}, {w[1]}] | {f['n']} | {f['tau_star']:.5f} ± {f['tau_star_err']:.5f}{flag} "
                  f"| {f['m_L']:.3f} ± {f['m_L_err']:.3f} | {f['m_beta']:.3f} ± {f['m_beta_err']:.3f} "
                  f"| {f['rms']:.1e} | {fl['tau_star']:.5f} ± {fl['tau_star_err']:.5f} "
                  f"| {fl['m_L']:.3f} ± {fl['m_L_err']:.3f} | {fb['tau_star']:.5f} ± {fb['tau_star_err']:.5f} "
                  f"| {fb['m_beta']:.3f} ± {fb['m_beta_err']:.3f} |")
    # τ̃*-free forms along the family, parametrised by β: q = τ̃* + B (1−β)^p (p = 1/m_β) and
    # L = A (1−β)^(−r) (paper: p = 1/2, r = 3/2)
    print("\nParametrised by 1 − β (no τ̃* in the L law): q = τ̃* + B(1−β)^p, L = A(1−β)^(−r)")
    print("| data | 1−β range | n | τ̃* | p (paper 1/2) | m_β = 1/p | r (paper 3/2) |")
    print("|---|---|---|---|---|---|---|")
    for name, sel in sets.items():
        for bmax in (0.1, 0.05, 0.03, 0.02):
            m = sel & (1 - b <= bmax)
            if m.sum() < 5:
                continue
            om = 1 - b[m]

            def res_q(pp, om=om, qq=q[m]):
                return pp[0] + pp[1] * om ** pp[2] - qq
            fq = least_squares(res_q, [1.008, 0.05, 0.5])
            cq = np.linalg.pinv(fq.jac.T @ fq.jac) * (fq.fun @ fq.fun) / max(m.sum() - 3, 1)
            eq = np.sqrt(np.diag(cq))
            cL = np.polyfit(np.log(om), np.log(L[m]), 1, cov=True)
            print(f"| {name} | ≤ {bmax} (to {om.min():.2e}) | {m.sum()} | {fq.x[0]:.5f} ± {eq[0]:.5f} "
                  f"| {fq.x[2]:.3f} ± {eq[2]:.3f} | {1 / fq.x[2]:.2f} | {-cL[0][0]:.3f} ± "
                  f"{math.sqrt(cL[1][0, 0]):.3f} |")
    # the paper's law on the same pulses
    deep = q < 1.03
    bm, Ltm = an.scaling_law(q[deep], PAPER_SCALING["tau_star"], PAPER_SCALING["a_v"],
                             PAPER_SCALING["a_G"], P)
    print("\nPaper Eqs. 3–4 (τ̃* = 1.0087, a_v = 1.15, a_G = 0.69) against the pulses:")
    print("| τ_d/τ_min | N | β | β (paper) | 1−β | 1−β (paper) | L (m) | L (paper, m) |")
    print("|---|---|---|---|---|---|---|---|")
    idx = np.nonzero(deep)[0]
    for j in sorted(set(np.linspace(0, idx.size - 1, 12).astype(int)), key=lambda j: -q[idx[j]]):
        i = idx[j]
        print(f"| {q[i]:.6f} | {N[i]} | {b[i]:.6f} | {bm[j]:.6f} | {1 - b[i]:.3e} | {1 - bm[j]:.3e} "
              f"| {L[i]:.4g} | {Ltm[j] * P.L_Gc:.4g} |")
    # edges
    tau_m = min(p.tau.min() for p in pulses)
    rows = [edge_measures(p, tau_m) for p in sorted(pulses, key=lambda p: p.L)
            if p.tau_d_ratio < 1.06]
    keep = []
    for r in rows:            # one per ~10 % in L
        if not keep or r["L"] > 1.1 * keep[-1]["L"]:
            keep.append(r)
    print("\nEdge structure against L (τ_m = min τ of all pulses):")
    print("| τ_d/τ_min | N | L (m) | √(1−β²) | v_max (m/s) | v_max√(1−β²) | τ_max/τ_min | ℓ (mm) | "
          "ℓ/√(1−β²) (mm) | e-fold ahead (mm) | e-fold/√(1−β²) (mm) | healing width (m) | "
          "Ḡ(1 µm) | Ḡ(2 µm) | Ḡ(5 µm) (J/m²) | Ḡ_max |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in keep:
        g = math.sqrt(1 - r["beta"] ** 2)
        print(f"| {r['q']:.5f} | {r['N']} | {r['L']:.4g} | {g:.4f} | {r['v_max']:.4g} "
              f"| {r['v_max'] * g:.4g} | {r['tau_max']:.5f} "
              f"| {1e3 * r['ell']:.4g} | {1e3 * r['ell'] / g:.4g} | {1e3 * r['efold']:.4g} "
              f"| {1e3 * r['efold'] / g:.4g} | {r['heal_width']:.4g} "
              f"| {r['G1']:.4g} | {r['G2']:.4g} | {r['G5']:.4g} | {r['G_max']:.4g} |")
    os.makedirs(a.outdir, exist_ok=True)
    key = ("family file, N = 2000", (1.0, 1.02))
    f = fits.get(key)
    if f is not None:
        fig = Figure(figsize=(9, 4))
        ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
        for n_, mk in ((2000, "o"), (4000, "s")):
            s_ = (N == n_) & (q - f["tau_star"] > 0) & (q < 1.05)
            d = q[s_] - f["tau_star"]
            ax1.loglog(d, L[s_], mk, ms=3, mfc="none", label=f"pulses, N = {n_}")
            ax2.loglog(d, 1 - b[s_], mk, ms=3, mfc="none", label=f"pulses, N = {n_}")
        dd = np.geomspace(0.5 * (q.min() - f["tau_star"]), 0.05, 100)
        ax1.loglog(dd, np.exp(f["ln_A"]) * dd ** (-f["m_L"]), "k-",
                   label=f"fit: m_L = {f['m_L']:.2f}, τ̃* = {f['tau_star']:.5f}")
        ax2.loglog(dd, np.exp(f["ln_B"]) * dd ** f["m_beta"], "k-", label=f"fit: m_β = {f['m_beta']:.2f}")
        xx = PAPER_SCALING["tau_star"] + dd
        bp, Lp = an.scaling_law(xx, PAPER_SCALING["tau_star"], PAPER_SCALING["a_v"], PAPER_SCALING["a_G"], P)
        ax1.loglog(xx - f["tau_star"], Lp * P.L_Gc, "r--", label="paper Eqs. 3–4 (τ̃* = 1.0087)")
        ax2.loglog(xx - f["tau_star"], 1 - bp, "r--", label="paper Eqs. 3–4")
        ax1.set_xlabel("τ_d/τ_min − τ̃*"), ax1.set_ylabel("L (m)")
        ax2.set_xlabel("τ_d/τ_min − τ̃*"), ax2.set_ylabel("1 − β")
        ax1.legend(fontsize=7), ax2.legend(fontsize=7)
        fig.suptitle("L and 1 − β against τ_d/τ_min − τ̃*, τ̃* from the joint fit on [1.0, 1.02] "
                     "(family file, N = 2000); paper's law drawn on the same axis")
        fig.tight_layout()
        for ext in ("png", "pdf"):
            fig.savefig(os.path.join(a.outdir, f"divergence.{ext}"), dpi=140)
    fig = Figure(figsize=(10, 3.4))
    axs = [fig.add_subplot(1, 3, k) for k in (1, 2, 3)]
    Ls = np.array([r["L"] for r in keep])
    gs = np.array([math.sqrt(1 - r["beta"] ** 2) for r in keep])
    axs[0].semilogx(Ls, [1e3 * r["ell"] for r in keep], "o-", label="ℓ = ξ(τ_max) − ξ(v_max) (mm)")
    axs[0].semilogx(Ls, 1e3 * np.array([r["ell"] for r in keep]) / gs, "o--",
                    label="ℓ/√(1−β²) (mm)")
    axs[0].semilogx(Ls, [1e3 * r["efold"] for r in keep], "s-", label="e-fold length ahead (mm)")
    axs[0].semilogx(Ls, 1e3 * np.array([r["efold"] for r in keep]) / gs, "s--",
                    label="e-fold/√(1−β²) (mm)")
    axs[0].semilogx(Ls, [r["heal_width"] for r in keep], "^-", label="healing width (m)")
    axs[0].set_yscale("log"), axs[0].legend(fontsize=7), axs[0].set_xlabel("L (m)")
    axs[1].semilogx(Ls, [r["tau_max"] for r in keep], "o-", label="τ_max/τ_min")
    axs[1].semilogx(Ls, [r["tau_m"] for r in keep], "s-", label="τ_m/τ_min (pulse min)")
    axs[1].legend(fontsize=7), axs[1].set_xlabel("L (m)")
    for key_, lab in (("G1", "Ḡ(1 µm)"), ("G2", "Ḡ(2 µm)"), ("G5", "Ḡ(5 µm)"), ("G_max", "Ḡ_max")):
        axs[2].semilogx(Ls, [r[key_] for r in keep], "o-", label=lab)
    axs[2].set_yscale("log"), axs[2].legend(fontsize=7), axs[2].set_xlabel("L (m)")
    axs[2].set_ylabel("J/m²")
    fig.tight_layout()
    for ext in ("png", "pdf"):
        fig.savefig(os.path.join(a.outdir, f"edges.{ext}"), dpi=140)
    return 0


if __name__ == "__main__":
    sys.exit(main())
