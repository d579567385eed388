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


def cmd_motion(args) -> int:
    from ..timedomain.motion import SteadyLine, integrate, write_trajectory
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
    line = SteadyLine.from_family(args.file)
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
          f"travelled {traj.x[i]:.4g} m; wall={inf['wall_time']:.2f} s -> {out}")
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
                                  "(xarray-readable; docs/motion.md).")
    p.add_argument("file", metavar="FILE", nargs="+",
                   help="HDF5 family file(s) with stored spectra (several: their pulses taken "
                        "together, e.g. the branch above 1.2 tau_min and the family below)")
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
