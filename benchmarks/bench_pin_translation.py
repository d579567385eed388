"""The leading growth rate with translation pinned against unpinned: accuracy and cost side by
side, one pulse, one run (issue 17; docs/spectrum.md §5).

    python benchmarks/bench_pin_translation.py FAMILY.h5 td1.0500 [--ladders 2000:2 1000:2]

For each ladder N_0:levels the pulse is re-solved on N_0 √2^k points of one smooth map of its
grid, and the leading eigenvalue found on each level, once with the operator of the steady
Jacobian (unpinned) and once with translation pinned, by the library calls of `slippulse steady
stability` (``refine_leading``). The reference is the pinned ladder one level above the largest
asked for, extrapolated (Richardson). Prints s L/c_p, its estimated error, its actual distance
from the reference, and the wall time of each; and the time ratio of the unpinned default ladder
to the cheapest pinned ladder whose actual error is no larger.
"""
from __future__ import annotations

import argparse
import time

from slippulse.core.h5io import read_pulse
from slippulse.spectrum.refine import mapped_pulse, refine_leading
from slippulse.spectrum.pulse import order4_pulse, pulse_spectrum
from slippulse.steady.grid import GridMap


def ladder(pulse, params, gmap, n0, levels, pin, guess):
    t0 = time.perf_counter()
    p0 = mapped_pulse(params, pulse, gmap, n0).to_pulse()
    first = pulse_spectrum(p0, params, guesses=[guess * p0.c_p / p0.L], extra=False,
                           pin_translation=pin)
    ref = refine_leading(p0, params, first, gmap, levels, pin_translation=pin, source=pulse)
    s, e = ref.per_length()
    return ref, s, e, time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file")
    ap.add_argument("label")
    ap.add_argument("--ladders", nargs="+", default=["2000:2", "1000:2"],
                    help="N0:levels (default 2000:2 1000:2)")
    ap.add_argument("--guess", type=float, default=None, help="s L/c_p to start from")
    a = ap.parse_args(argv)
    pulse, params = read_pulse(a.file, a.label)
    pulse = order4_pulse(pulse, params)
    gmap = GridMap(pulse.xi)
    guess = a.guess
    if guess is None:
        from slippulse.spectrum.pulse import read_spectrum
        st = read_spectrum(a.file, a.label)
        guess = float(st["leading_s_per_L"]) if st else 1.0
    ladders = [tuple(int(x) for x in spec.split(":")) for spec in a.ladders]
    top = max(n0 * 2 ** (lv / 2) for n0, lv in ladders)
    refn = min(n0 for n0, _ in ladders)
    ref_levels = 1
    while refn * 2 ** ((ref_levels - 1) / 2) < top * 0.999:
        ref_levels += 1
    rref, s_ref, e_ref, t_ref = ladder(pulse, params, gmap, refn, ref_levels, True, guess)
    print(f"{a.label}: reference (pinned, N = {'/'.join(map(str, rref.n_points))}): "
          f"s L/c_p = {rref.s_extrapolated / rref.rate_unit:.8f} (Richardson; finest "
          f"{s_ref:.8f} ± {e_ref:.1e}), {t_ref:.0f} s")
    sref = rref.s_extrapolated / rref.rate_unit
    rows = []
    for n0, lv in ladders:
        for pin in (False, True):
            r, s, e, t = ladder(pulse, params, gmap, n0, lv, pin, guess)
            rows.append((pin, n0, lv, r, s, e, t))
            print(f"  {'pinned  ' if pin else 'unpinned'} N = {'/'.join(map(str, r.n_points)):>16}"
                  f"  s L/c_p = {s:.8f} ± {e:.1e}  actual error {abs(s - sref):.1e}  "
                  f"{t:7.1f} s  ({r.status})")
    base = [r for r in rows if not r[0] and r[1] == max(n0 for n0, _ in ladders)]
    if base:
        b = base[0]
        ok = [r for r in rows if r[0] and abs(r[4] - sref) <= abs(b[4] - sref)]
        if ok:
            c = min(ok, key=lambda r: r[6])
            print(f"time ratio unpinned N0 = {b[1]} / pinned N0 = {c[1]} (no larger actual error):"
                  f" {b[6] / c[6]:.2f}")


if __name__ == "__main__":
    main()
