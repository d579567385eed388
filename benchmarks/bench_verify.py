"""Speed–accuracy and failure map of the seeded-pulse verification (docs/dynamic.md §3–4).

Usage (from the repository root; needs the steady family runs/family_stab.h5, which
``python dynamic/stability.py family`` computes in ~1 min)::

    python benchmarks/bench_verify.py convergence     # ~20 min: one chart per τ_d
    python benchmarks/bench_verify.py failure         # ~10 min: the failure map
    python benchmarks/bench_verify.py plot            # redraw from the stored JSON

Each case seeds the steady pulse (``slippulse.timedomain.verify.verify_pulse``) and propagates it over a distance
D_τ chosen so that the pulse's own unstable mode grows by at most ~e^{1.2} (1.2 τ_min: 0.05 L, growth
24/L; 1.1 τ_min: 0.15 L, 8/L; 1.05 τ_min: 1 L, 0.6/L; docs/stability.md), so that the errors at
D_τ measure the discretisation and seeding, not the physics. The deviation-vs-distance series are
stored too: the instability shows as the same exponential slope at every resolution, the
discretisation error as a resolution-dependent offset.

Sweeps per τ_d (baseline Δx₀, ξ_s = 0.5, cheap SOE node set, 3 L behind + 2 L ahead):
``dx`` (2Δx₀, Δx₀, Δx₀/2 at ξ_s = 0.5), ``dt`` (ξ_s = 1, 0.5, 0.25 at Δx₀: the adaptive step's
friction-stability factor, which binds at 1.2 τ_min), ``cfl`` (β_cfl = 1, 0.25: the floor of the
adaptive step, Δt ≥ β_cfl Δx/c_s, which binds at 1.1 and 1.05 τ_min), ``both`` (Δx and ξ_s halved
together), ``history`` (the fine SOE node set), ``domain`` (2+2, 3+2, 4+4 L).

Results: benchmarks/results/verify_<what>.json (one object per case; a rerun skips the cases
already there), benchmarks/results/verify_<what>.md (tables) and benchmarks/figures/verify_*.png.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
FAMILY = "runs/family_stab.h5"
RESULTS = os.path.join(HERE, "results")
FIGURES = os.path.join(HERE, "figures")
#: τ_d label: (baseline Δx, distance D_τ in L)
TARGETS = {"td1.2000": (2e-3, 0.05), "td1.1000": (4e-3, 0.15), "td1.0500": (4e-3, 1.0)}
KEYS = ("c_p_error", "v_max_error", "L_error", "lnv_error")


def convergence_cases():
    cases = []
    for label, (dx0, dist) in TARGETS.items():
        base = dict(label=label, distance=dist, dx=dx0, xi_stab=0.5, history="cheap",
                    ahead=2.0, behind=3.0)

        def add(sweep, **kw):
            c = dict(base, sweep=sweep)
            c.update(kw)
            cases.append(c)
        for f in (2.0, 1.0, 0.5):
            add("dx", dx=dx0 * f)
        for xs in (1.0, 0.5, 0.25):
            add("dt", xi_stab=xs)
        for bc in (1.0, 0.25):           # the CFL-limited step (1.1 and 1.05 τ_min: ξ_s does not bind)
            add("cfl", beta_cfl=bc)
        for f in (2.0, 1.0, 0.5):
            add("both", dx=dx0 * f, xi_stab=0.5 * f)
        add("history", history="fine")
        for a, b in ((2.0, 2.0), (2.0, 3.0), (4.0, 4.0)):
            add("domain", ahead=a, behind=b)
    return cases


def failure_cases():
    """The failure map, at 1.05 τ_min (the cheapest nearly neutral pulse) over 0.5 L unless noted,
    and the adaptive step's stability factor at 1.2 τ_min (where it binds), over 0.05 L."""
    base = dict(label="td1.0500", distance=0.5, dx=4e-3, xi_stab=0.5, history="cheap",
                ahead=2.0, behind=3.0)
    out = [dict(base, sweep="baseline")]
    for xs in (1.0, 2.0, 4.0, 8.0):
        out.append(dict(base, sweep="xi_stab", xi_stab=xs))
    for bc in (1.0, 2.0):
        out.append(dict(base, sweep="fixed_dt", stepping="fixed", beta_cfl=bc))
    for dx in (8e-3, 16e-3, 32e-3):
        out.append(dict(base, sweep="coarse_dx", dx=dx))
    for xmax in (1e2, 1e1, 1e0):
        out.append(dict(base, sweep="short_history", history="short", soe_x_max=xmax))
    out.append(dict(base, sweep="quasi_dynamic", history="quasi_dynamic", distance=2.0))
    out.append(dict(base, sweep="history_at_rest", history_start="rest", distance=0.05))
    out.append(dict(base, sweep="wrap_dislocation", wrap_dislocation=True, far_field="none"))
    out.append(dict(base, sweep="no_far_field", far_field="none"))
    out.append(dict(base, sweep="follow_off", far_field="none", follow=False))
    # variable steps too large: at 1.2 τ_min the adaptive step is bound by ξ_s (not at 1.05)
    b12 = dict(label="td1.2000", distance=0.05, dx=2e-3, xi_stab=0.5, history="cheap",
               ahead=2.0, behind=3.0)
    for xs in (0.5, 1.0, 2.0, 4.0, 8.0):
        out.append(dict(b12, sweep="xi_stab_1.2", xi_stab=xs))
    # the quasi-dynamic model where the pulse is slow (β = 0.0072): does it survive there?
    out.append(dict(b12, sweep="quasi_dynamic_1.2", history="quasi_dynamic", distance=0.3))
    out.append(dict(b12, sweep="baseline_1.2", distance=0.3))
    return out


def case_key(c):
    return json.dumps({k: v for k, v in sorted(c.items())}, sort_keys=True)


def run_case(c, pulse, params):
    from slippulse.timedomain.verify import VerifySettings, verify_pulse
    from slippulse.timedomain.seeding import SOE_CHEAP, DomainSpec
    from slippulse.timedomain.perturbation import HISTORIES
    from slippulse.dynamics.stepper import TimeStepRule

    hist = c.get("history", "cheap")
    if hist == "short":
        opts = dict(SOE_CHEAP, x_max=c["soe_x_max"])
        policy = "soe"
    elif hist == "quasi_dynamic":
        opts, policy = None, "quasi_dynamic"
    else:
        opts, policy = HISTORIES[hist], "soe"
    rule = TimeStepRule(kind=c.get("stepping", "adaptive"), beta_cfl=c.get("beta_cfl", 0.5),
                        xi_stab=c["xi_stab"])
    spec = DomainSpec(dx=c["dx"], ahead=c["ahead"], behind=c["behind"])
    run = VerifySettings(rule=rule, n_samples=40, history_options=opts, history=policy,
                         history_start=c.get("history_start", "steady"),
                         wrap_dislocation=c.get("wrap_dislocation", False),
                         far_field=c.get("far_field", "steady"), follow=c.get("follow", True))
    res = verify_pulse(pulse, params, c["distance"], spec, run, progress=False)
    out = dict(c)
    out.update({k: res.errors[k] for k in KEYS})
    out.update(status=res.info["status"], wall_time=res.info["wall_time"],
               n_steps=res.info["n_steps"], n=res.info["n"], travelled=res.info["travelled"],
               c_p_mean_error=res.errors["c_p_mean_error"],
               t0_lnv_error=res.info["t0_lnv_error"],
               series={"distance": res.series["distance"].tolist(),
                       "v_max_error": res.series["v_max_error"].tolist(),
                       "lnv_error": res.series["lnv_error"].tolist()})
    return out


def run_all(what):
    from slippulse.core.h5io import read_pulse

    if not os.path.exists(FAMILY):
        sys.exit(f"{FAMILY} missing: run `python dynamic/stability.py family` first")
    path = os.path.join(RESULTS, f"verify_{what}.json")
    done = json.load(open(path)) if os.path.exists(path) else []
    have = {case_key({k: v for k, v in r.items() if k in r["_case"]}) for r in done}
    cases = convergence_cases() if what == "convergence" else failure_cases()
    pulses = {}
    warm = False
    for c in cases:
        if case_key(c) in have:
            continue
        if not warm:        # compile the numba kernels before anything is timed
            w = dict(cases[0], distance=0.01, dx=16e-3, history="cheap")
            run_case(w, *read_pulse(FAMILY, w["label"]))
            warm = True
        if c["label"] not in pulses:
            pulses[c["label"]] = read_pulse(FAMILY, c["label"])
        t0 = time.perf_counter()
        r = run_case(c, *pulses[c["label"]])
        r["_case"] = sorted(c)
        done.append(r)
        print(f"{c['label']} {c['sweep']:>16}: dx={c['dx'] * 1e3:g} mm xi_s={c['xi_stab']:g} "
              f"{c.get('history', 'cheap')} {c['behind']:g}+{c['ahead']:g} L -> "
              + " ".join(f"{k}={r[k]:.2e}" for k in KEYS)
              + f" [{r['status'][:50]}] {r['n_steps']} steps {time.perf_counter() - t0:.1f} s",
              flush=True)
        with open(path + ".part", "w") as fh:
            json.dump(done, fh)
        os.replace(path + ".part", path)
    return done


def table(rows, what):
    lines = ["| τ_d | sweep | Δx (mm) | ξ_s | β_cfl | history | behind+ahead (L) | D (L) | N | steps | "
             "wall (s) | c_p (last ¼) | c_p (mean) | v_max | L | ln v | status |", "|" + "---|" * 17]
    for r in rows:
        lines.append(
            f"| {r['label'][2:]} | {r['sweep']} | {r['dx'] * 1e3:g} | {r['xi_stab']:g} | "
            f"{r.get('beta_cfl', 0.5):g}{'' if r.get('stepping', 'adaptive') == 'adaptive' else ' fixed'} | "
            f"{r.get('history', 'cheap')}{'' if 'soe_x_max' not in r else ' x_max=%g' % r['soe_x_max']} | "
            f"{r['behind']:g}+{r['ahead']:g} | {r['travelled']:.3f} | {r['n']} | {r['n_steps']} | "
            f"{r['wall_time']:.1f} | {r['c_p_error']:.1e} | {r['c_p_mean_error']:.1e} | "
            + " | ".join(f"{r[k]:.1e}" for k in KEYS[1:]) + f" | {r['status'][:60]} |")
    out = os.path.join(RESULTS, f"verify_{what}.md")
    with open(out, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    return out


def plot_convergence(rows):
    from matplotlib.figure import Figure
    from matplotlib.ticker import NullFormatter

    marks = {"dx": "o-", "dt": "s-", "cfl": "<-", "both": "D-", "history": "^", "domain": "v-"}
    paths = []
    fig = Figure(figsize=(12, 7.6))
    axes = fig.subplots(2, 3)
    for j, label in enumerate(TARGETS):
        ax, bx = axes[0, j], axes[1, j]
        sel = [r for r in rows if r["label"] == label]
        for sweep, m in marks.items():
            rr = [r for r in sel if r["sweep"] == sweep]
            if not rr:
                continue
            if sweep == "cfl":      # with the base point, which has β_cfl = 0.5
                rr = rr + [r for r in sel if r["sweep"] == "dt" and r["xi_stab"] == 0.5]
            rr.sort(key=lambda r: r["wall_time"])
            err = [max(abs(r["v_max_error"]), abs(r["c_p_mean_error"]), r["lnv_error"]) for r in rr]
            ax.loglog([r["wall_time"] for r in rr], err, m, ms=5, lw=1, label=sweep)
        ax.set_title(f"τ_d = {label[2:]} τ_min, after {TARGETS[label][1]:g} L", fontsize=9)
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel("max(|mean c_p err|, |v_max err|, ln v err)")
        ax.legend(fontsize=7)
        ax.xaxis.set_minor_formatter(NullFormatter())
        for r in sel:
            if r["sweep"] in ("both",):
                s = r["series"]
                bx.semilogy(s["distance"], np.abs(s["v_max_error"]), lw=1,
                            label=f"Δx={r['dx'] * 1e3:g} mm, ξ_s={r['xi_stab']:g}")
        bx.set_xlabel("distance travelled / L")
        bx.set_ylabel("|v_max err|")
        bx.legend(fontsize=7)
    fig.tight_layout()
    p = os.path.join(FIGURES, "verify_convergence.png")
    fig.savefig(p, dpi=120)
    paths.append(p)
    return paths


def _failure_label(r):
    sw = r["sweep"]
    if sw in ("xi_stab", "xi_stab_1.2"):
        return f"{r['label'][2:6]}: ξ_s = {r['xi_stab']:g}"
    if sw == "fixed_dt":
        return f"{r['label'][2:6]}: fixed Δt, β_cfl = {r['beta_cfl']:g}"
    if sw == "coarse_dx":
        return f"{r['label'][2:6]}: Δx = {r['dx'] * 1e3:g} mm"
    if sw == "short_history":
        return f"{r['label'][2:6]}: SOE x_max = {r['soe_x_max']:g}"
    return f"{r['label'][2:6]}: {sw.replace('_1.2', '').replace('_', ' ')}"


def plot_failure(rows):
    """Failure map: the worst error of each case (log scale), lost pulses marked."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 0.28 * len(rows) + 1.2))
    ax = fig.add_subplot()
    y = np.arange(len(rows))[::-1]
    for yi, r in zip(y, rows):
        vals = [abs(r[k]) for k in ("c_p_mean_error", "v_max_error", "L_error", "lnv_error")
                if r.get(k) is not None and math.isfinite(r[k])]
        lost = r["status"].startswith("pulse lost")
        err = max(vals) if vals and not lost else 1.0
        base = "baseline" in r["sweep"]
        ax.barh(yi, err, color="0.5" if base else ("C3" if lost or err > 1e-2 else "C0"))
        note = r["status"].split(":")[1].strip() if lost else f"{err:.1e}"
        ax.text(err * 1.15, yi, note + f"  (after {r['travelled']:.3g} L)", va="center", fontsize=6)
    ax.set_yticks(y, [_failure_label(r) for r in rows], fontsize=7)
    ax.set_xscale("log")
    ax.set_xlim(1e-5, 1e3)
    ax.axvline(1e-2, color="k", lw=0.6, ls=":")
    ax.set_xlabel("worst of |c_p|, |v_max|, |L|, ln v errors (red: > 1e-2 or pulse lost; grey: "
                  "baselines — at 1.2 τ_min over 0.3 L the unstable mode)", fontsize=7)
    fig.tight_layout()
    p = os.path.join(FIGURES, "verify_failure.png")
    fig.savefig(p, dpi=120)
    return p


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=("convergence", "failure", "plot"))
    a = ap.parse_args()
    os.makedirs(RESULTS, exist_ok=True)
    os.makedirs(FIGURES, exist_ok=True)
    if a.what == "plot":
        for what in ("convergence", "failure"):
            p = os.path.join(RESULTS, f"verify_{what}.json")
            if os.path.exists(p):
                rows = json.load(open(p))
                table(rows, what)
                print(plot_convergence(rows) if what == "convergence" else plot_failure(rows))
        return 0
    rows = run_all(a.what)
    table(rows, a.what)
    print(plot_convergence(rows) if a.what == "convergence" else plot_failure(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
