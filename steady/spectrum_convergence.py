"""Convergence of the leading eigenvalue in N and in the domain (docs/stability.md §8).

Two studies of the pulses of a family file:

* ``variants``: each pulse re-solved by the steady solver on grids adapted to it with N and 2N
  points and with the domain ahead / behind halved and doubled;
* ``nested`` (--nested K): the family pulse's own grid refined K times by inserting midpoints (the
  steady equations re-solved by Newton on each refined grid), so that the discretisation error
  falls smoothly and can be extrapolated (Richardson, order measured from three levels).

The leading eigenvalue of each is computed from the first one as the start. Prints a table and
writes JSON.

    python steady/spectrum_convergence.py runs/steady/family.h5 td1.2000 td1.0500 \
        --out runs/steady/spectrum_variants.json                   # ≈ 2–4 min per label
    python steady/spectrum_convergence.py runs/steady/family.h5 td1.0500 --nested 1 \
        --out runs/steady/spectrum_nested.json                     # ≈ 3 min per label (2 cores)
"""
from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

import numpy as np

from slippulse.core.h5io import read_pulse
from slippulse.steady.solver import GridSpec, refine_nested, solve_pulse
from slippulse.stability.spectrum import pulse_spectrum


def variants(n):
    base = GridSpec()
    return [("N", n, base), ("2N", 2 * n, base),
            ("ahead/2", n, replace(base, ahead=base.ahead / 2)),
            ("ahead*2", n, replace(base, ahead=base.ahead * 2)),
            ("behind/2", n, replace(base, behind_tail=base.behind_tail / 2)),
            ("behind*2", n, replace(base, behind_tail=base.behind_tail * 2))]


def nested(file, lab, levels):
    """Leading eigenvalue on the family grid and on `levels` nested midpoint refinements."""
    pulse, params = read_pulse(file, lab)
    rows, ref, p = [], None, pulse
    for lev in range(levels + 1):
        if lev > 0:
            sol = refine_nested(params, p)
            if not sol.stats.converged:
                print(f"{lab} nested {lev}: steady Newton failed: {sol.stats.message}", flush=True)
                break
            p = sol.to_pulse()
        t1 = time.perf_counter()
        res = pulse_spectrum(p, params, guesses=[] if ref is None else [ref * p.c_p / p.L],
                             extra=False)
        if res.sigmas.size == 0:
            print(f"{lab} nested {lev}: no eigenvalue ({res.message})", flush=True)
            break
        s = res.leading / res.rate_unit
        ref = s
        rows.append(dict(label=lab, level=lev, N=p.n_points, beta=p.beta, L=p.L,
                         sL_c=s.real, sL_c_imag=s.imag,
                         translation=(res.neutral[1] / res.rate_unit).real,
                         spectrum_s=time.perf_counter() - t1))
        print(f"{lab} nested {lev} N={p.n_points:5d} beta={p.beta:.8f} L={p.L:.6g} m "
              f"sigma L/c={s.real:.6f} (Im {s.imag:.1e}) sigma_t L/c={rows[-1]['translation']:.2e}",
              flush=True)
    if len(rows) >= 2:
        a, b = rows[-2]["sL_c"], rows[-1]["sL_c"]
        order = 2.0
        if len(rows) >= 3:
            d1, d2 = rows[-3]["sL_c"] - a, a - b
            if d1 * d2 > 0 and abs(d2) > 0:
                order = float(np.log2(abs(d1 / d2)))
        ext = b + (b - a) / (2 ** order - 1)
        rows[-1].update(extrapolated=ext, uncertainty=abs(b - a) / (2 ** order - 1),
                        order=order)
        print(f"{lab} extrapolated sigma L/c = {ext:.5f} ± {abs(b - a) / (2 ** order - 1):.1e} "
              f"(order {order:.2f})", flush=True)
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file")
    ap.add_argument("labels", nargs="+")
    ap.add_argument("--points", type=int, default=2000)
    ap.add_argument("--only", nargs="*", default=None, help="variant names to run")
    ap.add_argument("--out", default=None)
    ap.add_argument("--nested", type=int, default=0, help="nested refinement levels (study 2)")
    args = ap.parse_args(argv)
    rows = []
    if args.nested:
        for lab in args.labels:
            rows += nested(args.file, lab, args.nested)
            if args.out:
                with open(args.out, "w") as fh:
                    json.dump(rows, fh, indent=1)
        return
    for lab in args.labels:
        pulse, params = read_pulse(args.file, lab)
        guess = (pulse.xi, np.log(pulse.v), pulse.beta)
        ref = None
        for name, n, spec in variants(args.points):
            if args.only and name not in args.only and name != "N":
                continue
            t0 = time.perf_counter()
            sol = solve_pulse(params, pulse.tau_d_ratio, n_points=n, guess=guess, passes=0,
                              spec=spec)
            if not sol.stats.converged:
                print(f"{lab} {name}: steady solve failed: {sol.stats.message}", flush=True)
                continue
            p = sol.to_pulse()
            t1 = time.perf_counter()
            res = pulse_spectrum(p, params, guesses=[] if ref is None else [ref], extra=False)
            t2 = time.perf_counter()
            if res.sigmas.size == 0:
                print(f"{lab} {name}: no eigenvalue ({res.message})", flush=True)
                continue
            s = res.leading
            ref = s if ref is None else ref
            row = dict(label=lab, variant=name, N=n, beta=p.beta, L=p.L,
                       sigma_re=s.real, sigma_im=s.imag, sL_c=(s / res.rate_unit).real,
                       translation=(res.neutral[1] / res.rate_unit).real,
                       steady_s=t1 - t0, spectrum_s=t2 - t1)
            rows.append(row)
            print(f"{lab} {name:9s} N={n:5d} beta={p.beta:.7f} L={p.L:.6g} m  "
                  f"sigma L/c={row['sL_c']:.6f} (Im {s.imag / res.rate_unit:.1e})  "
                  f"sigma_t L/c={row['translation']:.2e}  steady {t1 - t0:.1f} s, "
                  f"spectrum {t2 - t1:.1f} s", flush=True)
            if args.out:
                with open(args.out, "w") as fh:
                    json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
