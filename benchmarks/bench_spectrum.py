"""Cost of the stability spectrum per pulse against the pulse's own steady solve, side by side.

    python benchmarks/bench_spectrum.py runs/steady/family.h5 td1.2000 td1.1000 td1.0500 td1.0300

For each label: the steady solve of that pulse as the family does it (from its neighbour, on a grid
adapted to the guess, N of the file), then the spectrum of the solved pulse tracked from the
neighbour's leading eigenvalue (what `slippulse steady stability` does along a family): leading
eigenvalue + neutral pair only, and with the search below the leading one. Prints wall times, the
stage split and the ratios to the steady solve.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from slippulse.core.h5io import list_pulses, read_pulse
from slippulse.steady.solver import solve_pulse
from slippulse.spectrum.pulse import pulse_spectrum


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file")
    ap.add_argument("labels", nargs="+")
    args = ap.parse_args(argv)
    labels = list_pulses(args.file)
    print(f"load average at start: {os.getloadavg()}")
    print("| pulse | N | steady solve (s) | spectrum, leading (s) | ratio | with search below (s) "
          "| ratio | s L/c_p |")
    print("|---|---|---|---|---|---|---|---|")
    for lab in args.labels:
        pulse, params = read_pulse(args.file, lab)
        k = labels.index(lab)
        nb = read_pulse(args.file, labels[max(k - 1, 0)])[0]
        t0 = time.perf_counter()
        sol = solve_pulse(params, pulse.tau_d_ratio, n_points=pulse.n_points,
                          guess=(nb.xi, np.log(nb.v), nb.beta), passes=0)
        t_steady = time.perf_counter() - t0
        p = sol.to_pulse() if sol.stats.converged else pulse
        # the neighbour's eigenvalue as the tracking start, as in a family run
        ref = pulse_spectrum(nb, params, extra=False)
        guess = [ref.leading / ref.rate_unit * p.c_p / p.L] if ref.sigmas.size else []
        modes = None
        if ref.modes:                       # the neighbour's mode moved over in ξ/L, as run_spectrum
            V, x0, x = ref.modes[0]["V"], nb.xi / nb.L, p.xi / p.L
            modes = [np.interp(x, x0, V.real) + 1j * np.interp(x, x0, V.imag)]
        r1 = pulse_spectrum(p, params, guesses=guess, extra=False, guess_modes=modes)
        r2 = pulse_spectrum(p, params, guesses=guess, extra=True, guess_modes=modes)
        s = r1.leading / r1.rate_unit
        print(f"| {lab} | {p.n_points} | {t_steady:.2f} | {r1.wall_time:.1f} "
              f"({', '.join(f'{k} {v:.1f}' for k, v in r1.stage_times.items())}) | "
              f"{r1.wall_time / t_steady:.1f}× | {r2.wall_time:.1f} | {r2.wall_time / t_steady:.1f}× "
              f"| {s.real:.4f} |", flush=True)
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
