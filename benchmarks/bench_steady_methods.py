"""Speed–accuracy of the steady method: work–precision, failure map, iteration counts/time split.

Run (each part ≤ ~5 min on the shared 2-core machine; one heavy process at a time):

    python benchmarks/bench_steady_methods.py wp       --family /tmp/fam2.h5
    python benchmarks/bench_steady_methods.py failure  --family /tmp/fam2.h5
    python benchmarks/bench_steady_methods.py domain   --family /tmp/fam2.h5
    python benchmarks/bench_steady_methods.py split    --family /tmp/fam2.h5

`--family` is a converged family file (``slippulse steady family`` 1.2 → 1.015, step 0.005,
N = 2000, cubic); it is only read. Each part prints markdown tables, writes them to
benchmarks/results/steady_methods_<part>.md and its figures to benchmarks/figures/.

Protocols (all solves: damped Newton, tol max|Δ| ≤ 1e-13, unless said otherwise)
* wp: seed = the family pulse at τ_d. Adapted-grid methods ("cubic", "linear"): the grid with N
  points adapted to the seed (GridSpec defaults: 120 L ahead, 40 healing lengths behind), seed
  interpolated onto it, one Newton solve. "fft": UNIFORM grid of N points on a truncated domain
  [x_f − a L, x_f + b L] around the seed's leading edge x_f, seed interpolated onto it (PCHIP in ln v),
  Hilbert operator :func:`hilbert_matrix_fft` (pad 2 = conventional zero-padded FFT, or the
  M → ∞ lattice kernel), with the same algebraic far-field tails as the cubic operator. Wall time:
  grid + interpolation + Hilbert assembly + Newton (numba warmed up). Reference: cubic, N = 8000.
* failure: (i) solve_pulse(params, r) from the built-in guess (N = 1000, two adapt passes);
  (ii) seed = family pulse at τ_d, target τ_d − Δ, solve_pulse(..., guess=(xi, ln v, β), passes=1,
  coarse_points=N, N = 1000, max_iter=40), no predictor.
* domain: seed = family pulse; solve_pulse(..., spec=GridSpec(ahead=A, behind_tail=B), N = 2000,
  passes=2, coarse_points=1000); A and B varied over a factor 16, one at a time.
* split: one continuation step (seed: family pulse at τ_d + 0.005) and, at 1.2, the full sequence
  from the built-in guess, pass by pass: Newton iterations, Hilbert assembly, Jacobian fills,
  LU, residual evaluations (line search); LM (scipy MINPACK) on the same final grid for comparison.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

from slippulse.core.h5io import list_pulses, read_pulse
from slippulse.steady.hilbert import hilbert_matrix, hilbert_matrix_fft
from slippulse.steady.newton import SOLVERS
from slippulse.core.params import DEFAULT
from slippulse.steady.measures import pulse_length
from slippulse.steady.solver import (GridSpec, adapted_grid, count_humps, default_guess, front_pin,
                              interpolate, solve_pulse)
from slippulse.steady.equations import SteadyProblem

HERE = os.path.dirname(os.path.abspath(__file__))
FIG = os.path.join(HERE, "figures")
RES = os.path.join(HERE, "results")
P = DEFAULT
OUT_LINES: list[str] = []


def emit(s=""):
    print(s, flush=True)
    OUT_LINES.append(s)


def write_results(part, argv):
    os.makedirs(RES, exist_ok=True)
    path = os.path.join(RES, f"steady_methods_{part}.md")
    with open(path, "w") as fh:
        fh.write(f"Command: `python benchmarks/bench_steady_methods.py {' '.join(argv)}`\n\n")
        fh.write("\n".join(OUT_LINES) + "\n")
    print(f"[written {path}]")


# ------------------------------------------------------------------------------------ helpers
def family_pulse(path, r):
    pu, _ = read_pulse(path, f"td{r:.4f}")
    return pu


def family_beta_L(path):
    rs, bs, Ls = [], [], []
    for lab in list_pulses(path):
        pu, _ = read_pulse(path, lab)
        rs.append(pu.tau_d_ratio), bs.append(pu.beta), Ls.append(pu.L)
    o = np.argsort(rs)
    return np.array(rs)[o], np.array(bs)[o], np.array(Ls)[o]


def family_points(path):
    """'2000' or '1000–1250': the grid sizes N of the pulses of a family file (for legends)."""
    ns = sorted({read_pulse(path, lab)[0].n_points for lab in list_pulses(path)})
    return f"{ns[0]}" if ns[0] == ns[-1] else f"{ns[0]}–{ns[-1]}"


def v_stick(r):
    return P.v_stick(r * P.tau_min)


def n_extrema(v):
    """Number of interior local extrema of ln v on the whole grid (2 for a clean pulse: the maximum
    and one shallow minimum in the healing tail): a spurious-oscillation count."""
    y = np.log(v)
    d = np.diff(y)
    d = d[np.abs(d) > 1e-10]
    return int(np.sum(np.sign(d[1:]) != np.sign(d[:-1])))


def newton_on(r, xi, y, beta, H=None, hilbert="cubic", max_iter=60, method="newton"):
    """One solve on a fixed grid, Hilbert assembly timed separately. Returns dict."""
    vs = v_stick(r)
    k, _ = front_pin(xi, y, math.log(vs))
    t0 = time.perf_counter()
    prob = SteadyProblem(P, r, xi, k, float(y[k]), hilbert=hilbert, H=H)
    t_h = time.perf_counter() - t0
    x, st = SOLVERS[method](prob, np.concatenate([y, [beta]]), tol=1e-13, max_iter=max_iter)
    v, phi, tau, _ = prob.fields(x)
    res = prob.residual(x)[:-1]
    mr = float(np.max(np.abs(res))) if np.all(np.isfinite(res)) else float("inf")
    return dict(prob=prob, x=x, st=st, t_h=t_h, v=v, phi=phi, beta=float(x[-1]),
                L=pulse_length(xi, v, P.v_star, crossings=False), maxres=mr,
                conv=bool(st.converged and mr <= 1e-13),
                it=st.iterations, humps=count_humps(v))


def seed_grid_adapted(pu, r, n, spec=GridSpec()):
    vs = v_stick(r)
    y0 = np.log(pu.v)
    xi = adapted_grid(pu.xi, y0, pu.phi, pu.beta, P, vs, n, spec)
    return xi, interpolate(pu.xi, y0, xi, vs)


def seed_uniform(pu, r, n, a, b):
    vs = v_stick(r)
    y0 = np.log(pu.v)
    k, _ = front_pin(pu.xi, y0, math.log(vs))
    xf = pu.xi[k]
    xi = np.linspace(xf - a * pu.L, xf + b * pu.L, n)
    return xi, interpolate(pu.xi, y0, xi, vs), xf


def warmup():
    solve_pulse(P, 1.2, n_points=200, coarse_points=200)
    hilbert_matrix_fft(np.linspace(-1, 1, 64), pad=None, tails=True, center=0.0)


def roughness(y):
    """|Δ⁴y_i|/16: amplitude of an odd–even (Nyquist) pattern in y (smooth y gives h⁴ y⁽⁴⁾/16)."""
    return np.abs(y[:-4] - 4 * y[1:-3] + 6 * y[2:-2] - 4 * y[3:-1] + y[4:]) / 16.0


def off_front_roughness(xi, v, L):
    """max |Δ⁴ ln v|/16 outside the leading-edge zone |ξ| < 0.1 L (ξ = 0 near the front)."""
    r = roughness(np.log(v))
    away = np.abs(xi[2:-2]) > 0.1 * L
    return float(r[away].max()) if away.any() else float("nan")


def repeats(n):
    """Timing repeats (the minimum is reported: the machine is shared)."""
    return 3 if n <= 1000 else (2 if n <= 2000 else 1)


def relerr(a, b):
    return abs(a / b - 1.0) if np.isfinite(a) else float("nan")


# ---------------------------------------------------------------------------- part 1: wp
def part_wp(args):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    warmup()
    ratios = args.ratios or [1.2, 1.05]
    n_adapt = args.points or [250, 500, 1000, 2000, 4000]
    n_fft = args.fft_points or [500, 1000, 2000, 4000]
    fft_variants = [("fft pad2 [-3L,+2L]", 2, 3.0, 2.0), ("fft lattice [-3L,+2L]", None, 3.0, 2.0),
                    ("fft lattice [-12L,+8L]", None, 12.0, 8.0),
                    # control: the cubic interpolating operator on the same uniform grid
                    ("cubic uniform [-3L,+2L]", "cubic", 3.0, 2.0)]
    allrows = {}
    lead = {}
    for r in ratios:
        pu = family_pulse(args.family, r)
        rows = []
        # reference
        t0 = time.perf_counter()
        xi, y = seed_grid_adapted(pu, r, args.ref_points)
        ref = newton_on(r, xi, y, pu.beta)
        ref_wall = time.perf_counter() - t0
        if not ref["conv"]:
            emit(f"REFERENCE NOT CONVERGED at {r}: {ref['st'].message}")
        bref, Lref = ref["beta"], ref["L"]
        rows.append(("cubic", args.ref_points, ref_wall, ref, xi))
        lead[(r, "ref")] = (xi, ref["v"])
        for kind in ("cubic", "linear"):
            for n in n_adapt:
                walls = []
                for _ in range(repeats(n)):
                    t0 = time.perf_counter()
                    xi, y = seed_grid_adapted(pu, r, n)
                    s = newton_on(r, xi, y, pu.beta, hilbert=kind)
                    walls.append(time.perf_counter() - t0)
                rows.append((kind, n, min(walls), s, xi))
                print(f"  {r} {kind} N={n} conv={s['conv']} it={s['it']} t={rows[-1][2]:.2f}",
                      flush=True)
        for name, pad, a, b in fft_variants:
            for n in n_fft:
                walls = []
                for _ in range(repeats(n)):
                    t0 = time.perf_counter()
                    xi, y, xf = seed_uniform(pu, r, n, a, b)
                    H = (hilbert_matrix(xi, kind=pad, center=0.0) if isinstance(pad, str)
                         else hilbert_matrix_fft(xi, pad=pad, tails=True, center=0.0))
                    t_h = time.perf_counter() - t0
                    s = newton_on(r, xi, y, pu.beta, H=H, max_iter=args.fft_max_iter)
                    s["t_h"] += t_h
                    walls.append(time.perf_counter() - t0)
                rows.append((name, n, min(walls), s, xi))
                lead[(r, name, n)] = (xi, s["v"], s["conv"])
                print(f"  {r} {name} N={n} conv={s['conv']} it={s['it']} t={rows[-1][2]:.2f} "
                      f"{s['st'].message[:60]}", flush=True)
        allrows[r] = (rows, bref, Lref)
        emit(f"\n### Work–precision, τ_d = {r} τ_min (wall: min of 3 repeats for N ≤ 1000, 2 for "
             f"N = 2000) (reference: cubic, N = {args.ref_points}: "
             f"β = {bref:.10f}, L = {Lref:.8f} m, {ref['it']} Newton it., {ref_wall:.1f} s)\n")
        emit("| operator / grid | N | h_min (m) | conv. | Newton it. | max abs(Δ) | wall (s) | t_H (s) "
             "| β | L (m) | rel. err β | rel. err L | humps | extrema of ln v "
             "| odd–even amp. off the front |")
        emit("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for name, n, wall, s, xi in rows[1:]:
            rough = (f"{off_front_roughness(xi, s['v'], Lref):.1e}" if "[" in name else "–")
            emit(f"| {name} | {n} | {np.min(np.diff(xi)):.2e} | {'yes' if s['conv'] else 'NO'} | "
                 f"{s['it']} | {s['maxres']:.1e} | {wall:.2f} | {s['t_h']:.2f} | {s['beta']:.8f} | "
                 f"{s['L']:.6f} | {relerr(s['beta'], bref):.1e} | {relerr(s['L'], Lref):.1e} | "
                 f"{s['humps']} | {n_extrema(s['v'])} | {rough} |")

    # ------------------------------------------------------------------ figure: work–precision
    styles = {"cubic": ("C0", "o"), "linear": ("C1", "s"), "fft pad2 [-3L,+2L]": ("C3", "^"),
              "fft lattice [-3L,+2L]": ("C2", "v"), "fft lattice [-12L,+8L]": ("C4", "D"),
              "cubic uniform [-3L,+2L]": ("C7", "P")}
    fig, axes = plt.subplots(2, len(ratios), figsize=(6.2 * len(ratios), 9), squeeze=False)
    for j, r in enumerate(ratios):
        rows, bref, Lref = allrows[r]
        for i, (q, key) in enumerate((("β", "beta"), ("L", "L"))):
            ax = axes[i, j]
            refv = bref if key == "beta" else Lref
            for name, (c, m) in styles.items():
                pts = [(w, relerr(s[key], refv), n, s["conv"]) for nm, n, w, s, _ in rows[1:]
                       if nm == name]
                if not pts:
                    continue
                w = np.array([p[0] for p in pts])
                e = np.array([max(p[1], 1e-9) if np.isfinite(p[1]) else np.nan for p in pts])
                ok = np.array([p[3] for p in pts])
                ax.loglog(w[ok], e[ok], color=c, marker=m, label=name)
                if (~ok).any():
                    ax.loglog(w[~ok], np.where(np.isfinite(e[~ok]), e[~ok], 1.0), ls="none",
                              marker="x", ms=11, mew=2, color=c)
                for p in pts:
                    ax.annotate(str(p[2]), (p[0], max(p[1], 1e-9) if np.isfinite(p[1]) else 1.0),
                                fontsize=7, xytext=(3, 3), textcoords="offset points", color=c)
            ax.axhline(1e-4, color="k", lw=0.5, ls=":")
            ax.set_xlabel("wall time per solve (s)")
            ax.set_ylabel(f"relative error of {q}")
            ax.set_title(f"τ_d = {r} τ_min: {q} (ref. cubic N={args.ref_points})")
            ax.grid(True, which="major", alpha=0.3)
            if i == 0 and j == 0:
                ax.legend(fontsize=8, title="× = Newton not converged (error of last iterate)",
                          title_fontsize=7)
    fig.tight_layout()
    os.makedirs(FIG, exist_ok=True)
    f1 = os.path.join(FIG, "steady_work_precision.png")
    fig.savefig(f1, dpi=110)
    plt.close(fig)

    # ------------------------------------------------------------------ figure: FFT leading edge
    fig, axes = plt.subplots(2, len(ratios), figsize=(6.2 * len(ratios), 8.4), squeeze=False)
    for j, r in enumerate(ratios):
        xr, vr = lead[(r, "ref")]
        Lref = allrows[r][2]
        ax, ax2 = axes[0, j], axes[1, j]
        ax.semilogy(xr / Lref, vr, "k-", lw=3, alpha=0.35, label=f"cubic adapted N={args.ref_points}")
        ax2.semilogy(xr[2:-2] / Lref, roughness(np.log(vr)) + 1e-17, "k.", ms=2, alpha=0.5,
                     label=f"cubic adapted N={args.ref_points}")
        for key, val in lead.items():
            if key[0] != r or key[1] == "ref":
                continue
            name, n = key[1], key[2]
            if n not in (n_fft[0], n_fft[-1]):
                continue
            xi, v, ok = val
            c = styles[name][0]
            lab = f"{name} N={n}" + ("" if ok else " (NOT converged)")
            alpha = 0.95 if n == n_fft[-1] else 0.45
            ax.semilogy(xi / Lref, v, ".-", ms=3, lw=0.8, color=c, alpha=alpha, label=lab)
            ax2.semilogy(xi[2:-2] / Lref, roughness(np.log(v)) + 1e-17, ".", ms=1.5, color=c,
                         alpha=alpha, label=lab)
        ax.set_xlim(-0.1, 0.12)
        ax.set_xlabel("ξ / L (leading edge at ≈ 0)")
        ax.set_ylabel("v (m/s)")
        ax.set_title(f"leading edge, τ_d = {r} τ_min (uniform grids)", fontsize=10)
        ax.legend(fontsize=7)
        ax.grid(True, alpha=0.3)
        ax2.set_xlabel("ξ / L (whole uniform domain)")
        ax2.set_xlim(-13, 9)
        ax2.set_ylim(1e-14, 10)
        ax2.set_ylabel("odd–even amplitude |Δ⁴ ln v|/16")
        ax2.set_title("odd–even (grid-scale) oscillation of ln v; colours as above, black: cubic "
                      "reference\n(on its graded grid Δ⁴ also measures the grading)", fontsize=9)
        ax2.grid(True, alpha=0.3)
    fig.tight_layout()
    f2 = os.path.join(FIG, "steady_fft_leading_edge.png")
    fig.savefig(f2, dpi=110)
    plt.close(fig)
    emit(f"\nFigures: {os.path.relpath(f1, HERE)}, {os.path.relpath(f2, HERE)}")


# ---------------------------------------------------------------------- part 2: failure
def part_failure(args):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    warmup()
    fr, fb, fL = family_beta_L(args.family)
    from scipy.interpolate import CubicSpline
    lnb, lnL = CubicSpline(fr, np.log(fb)), CubicSpline(fr, np.log(fL))

    def fam_beta(r):                      # family β (cubic spline in ln β between family pulses)
        return float(np.exp(lnb(r))) if fr.min() <= r <= fr.max() else float("nan")
    # (i) direct solves from the built-in guess
    direct = args.ratios or [1.3, 1.25, 1.22, 1.21, 1.2, 1.195, 1.19, 1.185, 1.18, 1.15, 1.12, 1.1,
                             1.08, 1.05, 1.03, 1.02]
    emit("\n### (i) Direct solve from the built-in guess (no continuation), N = 1000\n")
    emit("| τ_d/τ_min | result | Newton it. (last pass) | passes done | max abs(Δ) | β | family β | "
         "L (m) | family L | humps | wall (s) | message |")
    emit("|---|---|---|---|---|---|---|---|---|---|---|---|")
    drow = []
    for r in direct:
        t0 = time.perf_counter()
        s = solve_pulse(P, r, n_points=1000)
        wall = time.perf_counter() - t0
        pu = s.to_pulse()
        fbeta = fam_beta(r)
        fl = float(np.exp(lnL(r))) if np.isfinite(fbeta) else float("nan")
        same = pu.converged and pu.extra["n_humps"] == 1 and \
            (abs(pu.beta / fbeta - 1) < 5e-3 if np.isfinite(fbeta) else True)
        res = "pulse" if same else ("OTHER solution" if pu.converged else "FAILED")
        drow.append((r, res, pu.beta))
        emit(f"| {r} | {res} | {s.stats.iterations} | {s.passes} | {pu.max_residual:.1e} | "
             f"{pu.beta:.6g} | {fbeta:.6g} | {pu.L:.4g} | {fl:.4g} | {pu.extra['n_humps']} | "
             f"{wall:.2f} | {s.stats.message[:70]} |")
        print(f"  direct {r}: {res} {wall:.1f}s", flush=True)

    # (ii) largest continuation step
    starts = [1.2, 1.15, 1.1, 1.05, 1.03, 1.025, 1.02]
    deltas = [0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125]
    n = args.n_step
    grid = {}
    itc = {}
    emit(f"\n### (ii) Continuation step from the family pulse at τ_d to τ_d − Δ (no predictor), "
         f"N = {n}\n")
    emit("Cells: Newton iterations of the final solve, wall time of both solves, δβ = relative "
         "deviation from the family β (✓ converged to the pulse, ✗ not converged, "
         f"≠ converged elsewhere: β off the family curve (cubic spline of ln β through the "
         f"N = {family_points(args.family)} family) "
         "by > 5e-3, or more than one hump); wall time "
         "in s.\n")
    emit("| τ_d/τ_min | " + " | ".join(f"Δ={d}" for d in deltas) + " | largest Δ converging |")
    emit("|---" * (len(deltas) + 2) + "|")
    for r0 in starts:
        pu = family_pulse(args.family, r0)
        cells, best = [], None
        for d in deltas:
            tgt = round(r0 - d, 6)
            if tgt <= 1.0 + 1e-9:
                cells.append("n/a (τ_d ≤ τ_min)")
                grid[(r0, d)] = "na"
                continue
            t0 = time.perf_counter()
            try:
                s = solve_pulse(P, tgt, n_points=n, guess=(pu.xi, np.log(pu.v), pu.beta), passes=1,
                                coarse_points=n, max_iter=40)
                q = s.to_pulse()
                ok = q.converged
                fbeta = fam_beta(tgt)
                onfam = ok and abs(q.beta / fbeta - 1) < 5e-3 and q.extra["n_humps"] == 1
                it = s.stats.iterations
                msg = f"δβ {abs(q.beta / fbeta - 1):.0e}" if ok and np.isfinite(fbeta) else ""
            except Exception as exc:       # noqa: BLE001 — a failure is a result here
                ok, onfam, it, msg = False, False, -1, str(exc)[:40]
            wall = time.perf_counter() - t0
            if tgt < fr.min():
                onfam = ok and q.extra["n_humps"] == 1   # below the family: no reference β
            mark = "✓" if onfam else ("≠" if ok else "✗")
            grid[(r0, d)] = "ok" if onfam else ("other" if ok else "fail")
            itc[(r0, d)] = f"{it} it"
            cells.append(f"{mark} {it} it, {wall:.1f} s" + (f", {msg}" if msg else ""))
            if onfam and best is None:
                best = d
            print(f"  step {r0} -> {tgt}: {mark} it={it} {wall:.1f}s {msg}", flush=True)
        emit(f"| {r0} | " + " | ".join(cells) + f" | {best} |")

    # figure
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
    ax = axes[0]
    col = {"pulse": "C2", "OTHER solution": "C1", "FAILED": "C3"}
    ax.semilogy(fr, fb, "k-", lw=1, label=f"family (continuation, N = {family_points(args.family)})")
    for r, res, b in drow:
        ax.scatter([r], [b], s=90, color=col[res], marker="o" if res == "pulse" else "X", zorder=3)
    for k, c in col.items():
        ax.scatter([], [], color=c, label=f"direct: {k} (β of last iterate)")
    ax.set_xlabel("τ_d / τ_min")
    ax.set_ylabel("β")
    ax.set_title("(i) direct solve from the built-in guess (N=1000)")
    ax.legend(fontsize=8)
    ax = axes[1]
    code = {"ok": 0, "other": 1, "fail": 2, "na": 3}
    img = np.array([[code[grid[(r0, d)]] for d in deltas] for r0 in starts])
    from matplotlib.colors import ListedColormap
    ax.imshow(img.T, cmap=ListedColormap(["#4caf50", "#ff9800", "#e53935", "#dddddd"]), vmin=0, vmax=3,
              aspect="auto")
    for a_, r0 in enumerate(starts):
        for b_, d in enumerate(deltas):
            ax.text(a_, b_, itc.get((r0, d), ""), ha="center", va="center", fontsize=8)
    ax.set_xticks(range(len(starts)), [str(s) for s in starts])
    ax.set_yticks(range(len(deltas)), [str(d) for d in deltas])
    ax.set_xlabel("seed τ_d / τ_min")
    ax.set_ylabel("step Δ(τ_d/τ_min)")
    ax.set_title("(ii) one continuation step τ_d → τ_d − Δ, N=1000 (Newton it. in cells)\n"
                 "green: pulse, orange: converged elsewhere, red: not converged, grey: n/a", fontsize=10)
    fig.tight_layout()
    os.makedirs(FIG, exist_ok=True)
    f = os.path.join(FIG, "steady_failure_map.png")
    fig.savefig(f, dpi=110)
    plt.close(fig)
    emit(f"\nFigure: {os.path.relpath(f, HERE)}")


# ------------------------------------------------------------------------ part 3: domain
def part_domain(args):
    warmup()
    n = args.n_domain
    ratios = args.ratios or [1.05, 1.2]
    aheads = [3.0, 10.0, 30.0, 60.0, 120.0, 240.0, 480.0]       # 30–480: the factor-16 scan;
    behinds = [0.5, 2.0, 10.0, 20.0, 40.0, 80.0, 160.0]        # 3, 10 / 0.5, 2: where it breaks
    for r in ratios:
        pu = family_pulse(args.family, r)
        base = None
        rows = []
        for A, B in [(120.0, 40.0)] + [(a, 40.0) for a in aheads if a != 120.0] + \
                [(120.0, b) for b in behinds if b != 40.0]:
            t0 = time.perf_counter()
            s = solve_pulse(P, r, n_points=n, guess=(pu.xi, np.log(pu.v), pu.beta), passes=2,
                            coarse_points=1000, spec=GridSpec(ahead=A, behind_tail=B))
            q = s.to_pulse()
            wall = time.perf_counter() - t0
            if base is None:
                base = q
            rows.append((A, B, q, wall))
            print(f"  domain {r} A={A} B={B} conv={q.converged} {wall:.1f}s", flush=True)
        # discretisation yardstick: same default domain at 2N
        s2 = solve_pulse(P, r, n_points=2 * n, guess=(pu.xi, np.log(pu.v), pu.beta), passes=2,
                         coarse_points=1000)
        q2 = s2.to_pulse()
        emit(f"\n### Domain length at τ_d = {r} τ_min (N = {n}; default ahead 120 L, behind 40 "
             f"healing lengths c_p D/v_stick = {40 * base.beta * P.c_s * P.D / base.v_stick:.4g} m)\n")
        emit(f"Discretisation yardstick, default domain N = {n} → {2 * n}: Δβ/β = "
             f"{relerr(q2.beta, base.beta):.1e}, ΔL/L = {relerr(q2.L, base.L):.1e}.\n")
        emit("| ahead (L) | behind (healing lengths) | domain (m) | conv. | β | L (m) | Δβ/β vs default "
             "| ΔL/L vs default | v(ξ_1)/v_stick − 1 | v(ξ_N)/v_stick − 1 | wall (s) |")
        emit("|---|---|---|---|---|---|---|---|---|---|---|")
        for A, B, q, wall in sorted(rows, key=lambda t: (t[1] != 40.0, t[0], t[1])):
            emit(f"| {A:g} | {B:g} | [{q.xi[0]:.4g}, {q.xi[-1]:.4g}] | {'yes' if q.converged else 'NO'} "
                 f"| {q.beta:.10f} | {q.L:.8f} | {relerr(q.beta, base.beta):.1e} | "
                 f"{relerr(q.L, base.L):.1e} | {q.v[0] / q.v_stick - 1:.2e} | "
                 f"{q.v[-1] / q.v_stick - 1:.2e} | {wall:.2f} |")


# ------------------------------------------------------------------------- part 4: split
def part_split(args):
    warmup()
    n = args.n_split
    ratios = args.ratios or [1.195, 1.1, 1.05, 1.03, 1.02]
    emit(f"\n### Iterations and time split per pulse (N = {n} final, coarse passes 500; one "
         "continuation step from the family pulse at τ_d + 0.005, no predictor; first row: full "
         "sequence from the built-in guess)\n")
    emit("t_H: Hilbert matrix assembly; t_J: residual+Jacobian fills (state integration, O(N²)); "
         "t_LU: dense LU factor+solve; t_ls: residual evaluations in the line search; other: grid "
         "adaptation, interpolation, pulse diagnostics.\n")
    emit("| case | pass | N | Newton it. | t_H (s) | t_J (s) | t_LU (s) | t_ls (s) | pass total (s) |")
    emit("|---|---|---|---|---|---|---|---|---|")
    lm_cases = []
    cases = [("guess", 1.2, None)] + [("step", r, r + 0.005) for r in ratios]
    for label, r, r0 in cases:
        vs = v_stick(r)
        t_all = time.perf_counter()
        if r0 is None:
            xi, y, beta = default_guess(P, r, 500)
            passes = [None, 500, n]
        else:
            pu = family_pulse(args.family, round(r0, 4))
            xi, y, beta = pu.xi, np.log(pu.v), pu.beta
            phi = pu.phi
            passes = [500, 500, n]
        tot = np.zeros(5)
        for k, npts in enumerate(passes):
            t0 = time.perf_counter()
            if npts is not None:
                if k == 0:
                    xi_n = adapted_grid(xi, y, phi, beta, P, vs, npts)
                else:
                    xi_n = adapted_grid(xi, y, s["phi"], beta, P, vs, npts)
                y = interpolate(xi, y, xi_n, vs)
                xi = xi_n
            s = newton_on(r, xi, y, beta)
            st = s["st"]
            wall = time.perf_counter() - t0
            parts = np.array([s["t_h"], st.t_jacobian, st.t_linear, st.t_residual, wall])
            tot += parts
            emit(f"| {label} {r} | {k} | {xi.size} | {st.iterations}{'' if s['conv'] else ' NOT CONV'} | "
                 + " | ".join(f"{t:.3f}" for t in parts) + " |")
            y, beta = s["x"][:-1], s["beta"]
            if not s["conv"]:
                break
        emit(f"| {label} {r} | all | | | " + " | ".join(f"{t:.3f}" for t in tot[:4]) +
             f" | {time.perf_counter() - t_all:.3f} |")
        lm_cases.append((r, xi, y, beta, s))
    # LM vs Newton from the same perturbed start (the converged N-point solution's grid, seeded by
    # the family pulse at τ_d + 0.005 interpolated there)
    emit(f"\n### Newton vs Levenberg–Marquardt (scipy MINPACK, same Jacobian) on one grid, N = "
         f"{args.n_lm}: seed = family pulse at τ_d + 0.005 interpolated onto the grid adapted to it\n")
    emit("| τ_d/τ_min | solver | converged | iterations / f-evals | max abs(Δ) | β | wall (s) |")
    emit("|---|---|---|---|---|---|---|")
    for r in args.lm_ratios:
        pu = family_pulse(args.family, round(r + 0.005, 4))
        xi, y = seed_grid_adapted(pu, r, args.n_lm)
        for m in ("newton", "lm"):
            t0 = time.perf_counter()
            s = newton_on(r, xi, y, pu.beta, method=m, max_iter=60 if m == "newton" else 200)
            emit(f"| {r} | {m} | {'yes' if s['conv'] else 'NO'} | {s['it']} | {s['maxres']:.1e} | "
                 f"{s['beta']:.8f} | {time.perf_counter() - t0:.2f} |")


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("part", choices=["wp", "failure", "domain", "split"])
    ap.add_argument("--family", default="/tmp/fam2.h5")
    ap.add_argument("--ratios", type=float, nargs="+")
    ap.add_argument("--points", type=int, nargs="+", help="wp: N for cubic/linear")
    ap.add_argument("--fft-points", type=int, nargs="+", help="wp: N for the FFT variants")
    ap.add_argument("--fft-max-iter", type=int, default=30)
    ap.add_argument("--ref-points", type=int, default=8000)
    ap.add_argument("--n-step", type=int, default=1000)
    ap.add_argument("--n-domain", type=int, default=2000)
    ap.add_argument("--n-split", type=int, default=2000)
    ap.add_argument("--n-lm", type=int, default=1000)
    ap.add_argument("--lm-ratios", type=float, nargs="+", default=[1.195, 1.05])
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    {"wp": part_wp, "failure": part_failure, "domain": part_domain, "split": part_split}[args.part](args)
    emit(f"\nTotal run time of this part: {time.perf_counter() - t0:.0f} s.")
    write_results(args.part, argv)


if __name__ == "__main__":
    main()
