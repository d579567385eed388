"""``slippulse steady motion``: integrate the one-degree-of-freedom equation of motion of a pulse
along the steady line of a family with stored growth rates (docs/motion.md)."""
from __future__ import annotations

import math
import os

from ..core.errors import UsageError
from ..core.h5io import check_writable
from .checks import finite


def _default_out(args) -> str:
    base = os.path.splitext(os.path.basename(args.file[0]))[0]
    return os.path.join("runs", "motion", f"{base}_td{args.tau_d:.4f}_L{args.length:.4g}.h5")


def steady_line(files, records=None):
    """The steady line: family HDF5 files with stored spectra, or the family's CSV tables with
    the rates of record (--records)."""
    from ..timedomain.motion import SteadyLine, line_from_tables
    csv = [str(f).endswith(".csv") for f in files]
    if any(csv) and not all(csv):
        raise UsageError("FILE: give either HDF5 family files or CSV tables, not both")
    if all(csv):
        if not records:
            raise UsageError("CSV tables hold no growth rates: give --records TOML "
                             "(e.g. docs/results/records.toml)")
        for f in (*files, records):
            if not os.path.exists(f):
                raise UsageError(f"{f!r} does not exist")
        try:
            return line_from_tables(files, records)
        except (KeyError, ValueError) as exc:
            raise UsageError(f"--records/FILE: {exc}")
    if records:
        raise UsageError("--records goes with CSV tables; HDF5 files use their stored spectra")
    return SteadyLine.from_family(files)


def limits_line(lim) -> str:
    """One line: where the model's rear front stops and whether L diverges in finite time."""
    import math
    rear = ("the rear front never stops" if math.isnan(lim.L_heal_stops) else
            f"the rear front (c_p0 - dL/dt) stops at L={lim.L_heal_stops:.4g} m"
            + (f" and moves forward again at L={lim.L_heal_moves:.4g} m"
               if math.isfinite(lim.L_heal_moves) else ""))
    div = (f"finite-time divergence, {lim.t_rest:.3g} s after the end if dL/dt ~ L^p beyond"
           if lim.finite_time_divergence else "no finite-time divergence")
    return (f"growing side from L={lim.L[0]:.5g} m: {rear}; long end L={lim.L[-1]:.5g} m reached "
            f"at t={lim.t_end:.4g} s, dL/dt={lim.rate[-1]:.4g} m/s ~ L^{lim.exponent_end:.2f}: "
            f"{div}; max dL/dt={lim.rate.max():.4g} m/s at L={lim.L[lim.rate.argmax()]:.4g} m")


def cmd_motion(args) -> int:
    from ..timedomain.motion import MotionInputError, integrate, limits, write_trajectory
    tau_d = finite(args.tau_d, "--tau-d", lo=0.0, unit="tau_min")
    L0 = finite(args.length, "--length", lo=0.0, unit="m")
    if args.duration is not None:
        finite(args.duration, "--duration", lo=0.0, unit="s")
    if args.points < 2:
        raise UsageError(f"--points={args.points} is invalid: must be an integer >= 2")
    out = args.out or _default_out(args)
    if os.path.exists(out) and not args.overwrite:
        raise UsageError(f"--out={out!r} exists; give --overwrite to replace it")
    check_writable(out, "--out")
    line = steady_line(args.file, args.records)
    duration = args.duration
    if duration is None:                       # ten e-folds of the steady pulse at tau_d
        lo, hi = line.tau_range
        if lo <= tau_d <= hi:
            s_eq = float(line.functions()[3](line.equilibrium(tau_d)))
            duration = 10.0 / s_eq
        else:
            duration = 1.0                     # integrate() refuses tau_d with its range
    traj = integrate(line, tau_d, L0, duration, n_out=args.points)
    write_trajectory(out, traj, line)
    i = int(max(k for k in range(traj.t.size) if math.isfinite(traj.L[k])))
    inf = traj.info
    fate = traj.fate + (f" at t = {traj.t_fate:.4g} s" if math.isfinite(traj.t_fate) else "")
    print(f"motion at tau_d/tau_min={tau_d:.6g} from L={L0:.5g} m (steady L*={inf['L_equilibrium']:.5g} m, "
          f"s*={inf['s_equilibrium']:.4g} 1/s): {fate}; at t={traj.t[i]:.4g} s L={traj.L[i]:.5g} m "
          f"[{traj.L_lo[i]:.5g}, {traj.L_hi[i]:.5g}] (s +- s_err, spline/PCHIP), "
          f"c_p={traj.c_p[i]:.5g} m/s [{traj.c_p_lo[i]:.5g}, {traj.c_p_hi[i]:.5g}], "
          f"travelled {traj.x[i]:.4g} m; wall={inf['wall_time']:.2f} s (cpu {inf['cpu_time']:.2f} s) -> {out}")
    try:
        print("model limits: " + limits_line(limits(line, tau_d)))
    except MotionInputError as exc:
        print(f"model limits: none ({exc})")
    return 0


def register(ss) -> None:
    """Add ``motion`` to the ``steady`` sub-commands."""
    p = ss.add_parser("motion", help="equation of motion of a pulse along the steady line",
                      description="Integrate dL/dt = s(L) (tau0(L) - tau_d) / (dtau0/dL), "
                                  "c_p = c_p0(L), from L(0) = --length under the uniform load "
                                  "--tau-d, with the steady line tau0(L), c_p0(L) and the growth "
                                  "rates s +- s_err of FILE (`slippulse steady stability`) "
                                  "interpolated in ln L. The band is the envelope over s +- s_err "
                                  "and two interpolants (cubic spline, PCHIP). Stops when L leaves "
                                  "the family. Writes L(t), c_p(t) and their band to HDF5 "
                                  "(xarray-readable; docs/motion.md), and prints the model's "
                                  "limits on the growing side: where the rear front "
                                  "(c_p0 - dL/dt) stops, and whether L diverges in finite "
                                  "time (docs/motion.md section 4).")
    p.add_argument("file", metavar="FILE", nargs="+",
                   help="HDF5 family file(s) with stored spectra (several: their pulses taken "
                        "together, e.g. the branch above 1.2 tau_min and the family below), "
                        "or the family's CSV tables with --records")
    p.add_argument("--records", default=None, metavar="TOML",
                   help="with CSV family tables as FILE (e.g. steady/seeds/deep_family_*.csv, "
                        "1 m - 10 km): the growth rates of record ([spectrum.LABEL] entries, "
                        "e.g. docs/results/records.toml)")
    p.add_argument("--tau-d", type=float, required=True,
                   help="uniform load tau_d/tau_min, within the family's rated pulses")
    p.add_argument("--length", type=float, required=True,
                   help="pulse length at t = 0 (m), within the family's rated range")
    p.add_argument("--duration", type=float, default=None,
                   help="time to integrate (s; default 10 e-folds of the steady pulse at tau_d)")
    p.add_argument("--points", type=int, default=400, help="output times (default 400)")
    p.add_argument("--out", default=None,
                   help="output HDF5 (default runs/motion/<FILE>_tdX_LY.h5)")
    p.add_argument("--overwrite", action="store_true", help="replace --out if it exists")
    p.set_defaults(func=cmd_motion)
