"""``slippulse dynamic run CONFIG.toml [--set section.key=value ...] [--resume] [--out FILE]``.

Runs the mode-III SBI time stepper (docs/dynamic.md) from a TOML config (dynamics/config.py), with a
tqdm progress bar (simulated time, steps/s) and a one-line summary at the end. Output: an HDF5 file
(dynamics/runfile.py) with snapshots, per-step scalars and checkpoints; ``--resume`` continues a run from its
last checkpoint, bit-identically to an uninterrupted run.
"""
from __future__ import annotations

import math
import os
import signal
import sys
import threading
import time

import numpy as np

from .app import UsageError
from .paramargs import add_params_args, check_config_params, config_sets, params_for_input
from ..core.h5io import check_writable
from .checks import check_distinct, check_figure, finite

#: Fewest points of a seeded grid (as --points of verify).
MIN_GRID_POINTS = 16


def register(subparsers) -> None:
    p = subparsers.add_parser("dynamic", help="time-dependent SBI simulations (mode III)",
                              description="Spectral boundary-integral elastodynamics of the "
                                          "rate-and-state interface (docs/dynamic.md).")
    sub = p.add_subparsers(dest="dynamic_command", metavar="SUBCOMMAND")
    sub.required = True
    r = sub.add_parser("run", help="run (or resume) a simulation from a TOML config",
                       description="Run an SBI simulation. Config precedence: built-in defaults, "
                                   "then CONFIG, then each --set. Unknown keys are errors.")
    r.add_argument("config", metavar="CONFIG.toml", help="run configuration (TOML)")
    r.add_argument("--set", dest="sets", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one config value (repeatable), e.g. --set grid.n=2048")
    r.add_argument("--resume", action="store_true",
                   help="continue from the last checkpoint stored in the output file")
    r.add_argument("--out", metavar="FILE", help="output HDF5 file (overrides output.file)")
    r.add_argument("--overwrite", action="store_true",
                   help="replace an existing output file (default: refuse)")
    r.add_argument("--no-progress", action="store_true", help="do not show the progress bar")
    add_params_args(r, with_set=False)      # --set params.NAME=VALUE is the config's own --set
    r.set_defaults(func=cmd_run)
    v = sub.add_parser("verify", help="propagate a seeded steady pulse and measure its drift",
                       description="Seed the SBI with a steady pulse (docs/dynamic.md §3), run it "
                                   "over DISTANCE pulse lengths in a frame that follows it and "
                                   "measure c_p, v_max, L and ln v against the steady solution.")
    v.add_argument("--steady", required=True, metavar="FILE", help="steady family file (HDF5 schema)")
    v.add_argument("--label", default=None, help="pulse group, e.g. td1.2000 (default: the only one)")
    v.add_argument("--distance", type=float, default=1.0, metavar="D",
                   help="distance to travel, in pulse lengths (default 1)")
    v.add_argument("--out", metavar="FILE", help="output HDF5 (default verify_<label>.h5); a PNG "
                                                  "(profiles, deviation, v_max drift against the "
                                                  "unstable mode's growth) is written beside it")
    v.add_argument("--points", type=int, default=None, metavar="N",
                   help="grid points; sets dx = (ahead + behind)·L/N (default: --dx)")
    v.add_argument("--dx", type=float, default=None,
                   help="grid spacing, m (default 2.26e-3 L0: 2e-3 for Table I)")
    v.add_argument("--ahead", type=float, default=4.0, help="domain ahead of the front, in L (4)")
    v.add_argument("--behind", type=float, default=4.0, help="domain behind the front, in L (4)")
    v.add_argument("--far-field", choices=("steady", "none"), default="steady",
                   help="add the isolated pulse's far field to the loading (default steady)")
    v.add_argument("--xi-stab", type=float, default=0.5, help="time.xi_stab of the adaptive rule")
    v.add_argument("--samples", type=int, default=100, help="measurements (default 100)")
    v.add_argument("--device", choices=("cpu", "cupy"), default="cpu",
                   help="where the steps run after seeding: cpu (default) or cupy, a CUDA GPU "
                        "through CuPy (the same scheme and history, in double precision)")
    _mode_args(v)
    v.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    v.add_argument("--allow-unconverged", action="store_true",
                    help="use a pulse marked converged=False (default: refuse it); the output "
                         "says so (attribute steady_converged = False)")
    v.add_argument("--no-progress", action="store_true", help="do not show the progress bar")
    add_params_args(v)
    v.set_defaults(func=cmd_verify)
    sd = sub.add_parser("seed", help="seed the SBI with a steady pulse and report the t = 0 mismatch",
                        description="Put a steady pulse on the periodic SBI grid with its steady past "
                                    "(docs/dynamic.md §3), write the t = 0 state (x, V, phi, delta, "
                                    "tau, tau_steady, tau_load) to HDF5 and print how far the SBI "
                                    "stress is from the steady one.")
    sd.add_argument("--steady", required=True, metavar="FILE", help="steady family file (HDF5 schema)")
    sd.add_argument("--label", default=None, help="pulse group, e.g. td1.2000 (default: the only one)")
    sd.add_argument("--out", metavar="FILE", help="output HDF5 (default seed_<label>.h5)")
    sd.add_argument("--dx", type=float, default=None,
                    help="grid spacing, m (default 2.26e-3 L0: 2e-3 for Table I)")
    sd.add_argument("--ahead", type=float, default=4.0, help="domain ahead of the front, in L (4)")
    sd.add_argument("--behind", type=float, default=4.0, help="domain behind the front, in L (4)")
    sd.add_argument("--far-field", choices=("steady", "none"), default="steady",
                    help="add the isolated pulse's far field to the loading (default steady)")
    sd.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    sd.add_argument("--allow-unconverged", action="store_true",
                    help="use a pulse marked converged=False (default: refuse it); the output "
                         "says so (attribute steady_converged = False)")
    _mode_args(sd)
    add_params_args(sd)
    sd.set_defaults(func=cmd_seed)
    try:                                   # ``dynamic scan`` (cli/scan.py)
        import importlib
        cli_scan = importlib.import_module("slippulse.cli.scan")
    except ModuleNotFoundError as exc:
        if exc.name != "slippulse.cli.scan":
            raise
    else:
        cli_scan.register(sub)
    from . import fate as cli_fate         # ``dynamic fate`` (cli/fate.py)
    cli_fate.register(sub)
    cli_fate.register_compare(sub)
    from . import growth as cli_growth     # ``dynamic growth-report`` (cli/growth.py)
    cli_growth.register(sub)
    from . import attractor as cli_attractor   # ``dynamic attractor`` (cli/attractor.py)
    cli_attractor.register(sub)
    from . import spectrum_report as cli_spectrum_report   # ``dynamic spectrum-report``
    cli_spectrum_report.register(sub)


def _mode_args(p) -> None:
    """--perturb/--eps/--mode-file: the eigenmode-seeded start (timedomain/eigenmode.py)."""
    p.add_argument("--perturb", choices=("none", "mode", "mode_front"), default="none",
                   help="'mode': add eps x the pulse's unstable eigenmode, with a past that grew "
                        "as exp(sigma t) (docs/stability.md section 2); 'mode_front': the same "
                        "mode with eps measured in the frame of the front and the front's "
                        "displacement carried exactly (docs/stability.md section 2; near tau_min the body then "
                        "gets eps instead of ~1e-3 eps)")
    p.add_argument("--eps", type=float, default=1e-3,
                   help="mode amplitude: largest change of ln(v/v*+1) (with mode_front: in the "
                        "frame of the front), 0 < |eps| <= 0.01 (default 1e-3)")
    p.add_argument("--mode-file", metavar="FILE", default=None,
                   help="take the stored mode from FILE (default: the steady file's spectrum, "
                        "else computed now); it must belong to the same pulse")


def _eigenmode(args, pulse, params, required: bool):
    """The pulse's eigenmode for --perturb mode (required) or for the drift verdict (None when
    it has none). Bad input (eps, a mode of another pulse, no spectrum) is a UsageError."""
    from ..core.params import ParameterError
    from ..timedomain.eigenmode import SpectrumError, check_eps, leading_mode, stored_mode
    try:
        if required:
            check_eps(args.eps)
        src = args.mode_file or args.steady
        if stored_mode(src, pulse.label) is None and not args.mode_file:
            print(f"no spectrum stored for {pulse.label} in {args.steady}: computing it "
                  f"(N = {pulse.xi.size}; 'slippulse steady stability' stores it)", file=sys.stderr)
        return leading_mode(pulse, params, path=args.steady, mode_path=args.mode_file)
    except SpectrumError as exc:
        if required or args.mode_file:
            raise UsageError(str(exc))
        print(f"note: {exc}", file=sys.stderr)
        return None
    except ParameterError as exc:
        raise UsageError(str(exc))


def cmd_run(args) -> int:
    """``slippulse dynamic run``: the SBI run of a config (the dynamics package is imported here,
    not when the CLI starts: pyfftw and dask cost every other command ≈ 0.7 s)."""
    from ..dynamics.config import RESUME_MUTABLE, build_stepper, diff_keys, load_config
    from ..dynamics.runfile import RunFile
    cfg = load_config(args.config, config_sets(args, args.sets))
    check_config_params(cfg)
    if args.out is not None:
        cfg["output"]["file"] = args.out
        check_writable(args.out, "--out")
    path = cfg["output"]["file"]
    if os.path.isdir(path):
        raise UsageError(f"--out={path!r} is a directory; give a file name (e.g. "
                         f"{os.path.join(path, 'run.h5')})")
    stepper = build_stepper(cfg)
    if args.resume:
        try:
            out, stored, state = RunFile.open_resume(path)
        except (FileNotFoundError, ValueError) as exc:
            raise UsageError(str(exc))
        changed = [k for k in diff_keys(stored, cfg) if k not in RESUME_MUTABLE]
        if changed:
            out.close()
            raise UsageError(f"--resume: config differs from the stored run in {', '.join(changed)}"
                             f" (only {', '.join(sorted(RESUME_MUTABLE))} may change)")
        try:
            stepper.load_state(state)
            out.update_config(cfg)
        except (KeyError, ValueError, TypeError, IndexError) as exc:
            out.close()
            raise UsageError(f"--resume: {path}: its checkpoint does not fit this run "
                             f"({type(exc).__name__}: {exc})") from None
    else:
        if os.path.exists(path) and not args.overwrite:
            raise UsageError(f"output file {path} exists: use --resume to continue it, --overwrite "
                             "to replace it, or --out for another file")
        check_writable(path, "--out")
        out = RunFile.create(path, cfg, stepper.params, stepper)
        try:
            out.snapshot(stepper)
            out.checkpoint(stepper)
        except BaseException:
            out.close()
            raise
    return drive(stepper, out, cfg, progress=not args.no_progress)


def drive(st, out: RunFile, cfg: dict, progress: bool = True) -> int:
    """Step to t_end / max_steps, writing snapshots, scalars and checkpoints on their cadences."""
    from tqdm import tqdm

    t_end = cfg["time"]["t_end"]
    max_steps = cfg["time"]["max_steps"] or None
    snap_every = cfg["output"]["snapshot_every"]
    ckpt_every = cfg["output"]["checkpoint_every"]
    wall0, n0 = time.perf_counter(), st.nstep
    bar = tqdm(total=t_end, initial=min(st.t, t_end), unit="s", disable=not progress,
               mininterval=0.5 if sys.stderr.isatty() else 10.0,
               bar_format="{l_bar}{bar}| t={n:.4g}/{total:.4g} s [{elapsed}<{remaining}{postfix}]")
    status, message, rc = "finished", "t_end reached", 0
    sigint = _StepBoundaryInterrupt()
    failed_write = None
    try:
        while st.t < t_end * (1 - 1e-14):
            if max_steps is not None and st.nstep >= max_steps:
                status, message = "stopped", f"max_steps={max_steps} reached"
                break
            if sigint.requested:
                raise KeyboardInterrupt
            dt = st.step()
            out.record_step(st)
            if st.nstep % snap_every == 0:
                out.snapshot(st)
            if st.nstep % ckpt_every == 0:
                out.checkpoint(st)
            bar.update(min(dt, max(t_end - bar.n, 0.0)))
            if st.nstep % 50 == 0:
                rate = (st.nstep - n0) / max(time.perf_counter() - wall0, 1e-9)
                bar.set_postfix_str(f"{rate:.0f} steps/s, Vmax={st.V.max():.3g} m/s", refresh=False)
    except FloatingPointError as exc:
        status, message, rc = "failed", str(exc), 1
    except KeyboardInterrupt:
        status, message, rc = "interrupted", "interrupted by the user", 130
    except OSError as exc:                       # a full disk: the work file is discarded
        failed_write = exc
    finally:
        sigint.restore()
        bar.close()
    if failed_write is None and status != "interrupted":
        try:
            if status == "finished" and out.last_snapshot_step() != st.nstep:
                out.snapshot(st)
            out.checkpoint(st, status=status, message=message)
        except OSError as exc:
            failed_write = exc
    if failed_write is not None:
        out.close()
        raise OSError(failed_write.errno, f"{failed_write.strerror or failed_write}; the run "
                      f"stopped at step {st.nstep}, {out.path} holds its last checkpoint "
                      "(--resume continues from it)", failed_write.filename or out.work)
    if status == "interrupted":
        # the state may be half-updated mid-step: keep FILE at its last checkpoint, marked
        out.close()
        _mark_interrupted(out)
    else:
        out.close()
    wall = time.perf_counter() - wall0
    print(f"slippulse dynamic: {status} ({message}); {st.nstep} steps, t = {st.t:.6g} s, "
          f"max V = {np.max(st.V):.4g} m/s, {(st.nstep - n0) / max(wall, 1e-9):.0f} steps/s, "
          f"{wall:.1f} s wall; output {out.path}", file=sys.stderr if rc else sys.stdout)
    return rc


#: Longest --distance of verify, in pulse lengths (each L takes ~1e3-1e4 steps; a pulse that is
#: lost ends the run earlier).
MAX_DISTANCE = 1e4


def _require_converged(args, pulse) -> None:
    """Refuse a pulse marked converged=False unless --allow-unconverged (h5io.require_converged)."""
    from ..core.h5io import require_converged
    require_converged(args.steady, [pulse.label], allow=args.allow_unconverged,
                      hint="--allow-unconverged uses it anyway and marks the output")


def _unconverged_prefix(pulse) -> str:
    return "" if pulse.converged else f"UNCONVERGED steady pulse {pulse.label} (--allow-unconverged): "


class _StepBoundaryInterrupt:
    """Ctrl-C (SIGINT) during a run, taken at a step boundary: the first one sets a flag that the
    loop reads between steps, so it cannot land inside a write, an FFT plan or a finalizer (where
    a KeyboardInterrupt may be swallowed); a second one raises KeyboardInterrupt at once. Only
    the main thread can install it; elsewhere the default behaviour stays."""

    def __init__(self):
        self.requested = False
        self._installed = threading.current_thread() is threading.main_thread()
        if self._installed:
            self._prev = signal.signal(signal.SIGINT, self._handler)

    def _handler(self, signum, frame):
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True

    def restore(self):
        if self._installed:
            signal.signal(signal.SIGINT, self._prev if self._prev is not None else signal.SIG_DFL)
            self._installed = False


def _mark_interrupted(out: RunFile) -> None:
    """Status 'interrupted' in FILE (its data stay at the last checkpoint; --resume continues)."""
    try:
        out.mark("interrupted", "interrupted by the user; the file holds the last checkpoint "
                                "(--resume continues from it)")
    except KeyboardInterrupt:
        pass                                   # a second Ctrl-C: FILE stays as it was


def _check_grid(dx: float, ahead: float, behind: float, L: float) -> None:
    """Refuse a seeded grid that is not finite or has more than MAX_GRID_POINTS points, before
    anything is allocated (``seeding.DomainSpec`` checks the signs)."""
    from ..dynamics.stepper import MAX_GRID_POINTS
    for name, val in (("dx", dx), ("ahead", ahead), ("behind", behind)):
        if not (math.isfinite(val) and val > 0):
            raise UsageError(f"--{name}={val!r} must be a finite number > 0")
    n = (ahead + behind) * L / dx
    if n < MIN_GRID_POINTS:
        raise UsageError(f"--dx={dx:g} m gives {n:.3g} grid points over ({ahead:g} + {behind:g}) "
                         f"L = {(ahead + behind) * L:.4g} m; at least {MIN_GRID_POINTS}")
    if n > MAX_GRID_POINTS:
        raise UsageError(f"--dx={dx:g} m gives {n:.3g} grid points over ({ahead:g} + {behind:g}) "
                         f"L = {(ahead + behind) * L:.4g} m; at most {MAX_GRID_POINTS}")


def cmd_verify(args) -> int:
    """``slippulse dynamic verify``: seed, propagate, measure, write HDF5 + PNG, print one line."""
    from ..core.h5io import SchemaError, check_writable, read_pulse
    from ..core.params import ParameterError
    from ..plotting.stability import plot_verify_result
    from ..timedomain.verify import VerifySettings, summary, verify_pulse, write_result
    from ..dynamics.stepper import MAX_GRID_POINTS
    from ..timedomain.seeding import DomainSpec
    from ..dynamics.stepper import TimeStepRule

    try:
        pulse, params = read_pulse(args.steady, args.label)
    except SchemaError as exc:
        raise UsageError(str(exc))
    _require_converged(args, pulse)
    params = params_for_input(args, params, args.steady)
    label = pulse.label
    out = f"verify_{label}.h5" if args.out is None else args.out
    check_writable(out, "--out")
    check_distinct(out, "--out", **{"--steady": args.steady, "--mode-file": args.mode_file})
    if os.path.exists(out) and not args.overwrite:
        raise UsageError(f"output file {out} exists: use --overwrite or another --out")
    check_writable(out, "--out")
    check_writable(os.path.splitext(out)[0] + ".png", "--out (its PNG)")
    finite(args.distance, "--distance", 0.0, MAX_DISTANCE, unit="pulse lengths")
    finite(args.xi_stab, "--xi-stab", 0.0)
    from ..timedomain.seeding import default_dx
    dx = default_dx(params) if args.dx is None else args.dx
    if args.points is not None:
        if not 16 <= args.points <= MAX_GRID_POINTS:
            raise UsageError(f"--points={args.points} must be in [16, {MAX_GRID_POINTS}]")
        dx = (args.ahead + args.behind) * pulse.L / args.points
    _check_grid(dx, args.ahead, args.behind, pulse.L)
    if not 2 <= args.samples <= 100_000:
        raise UsageError(f"--samples={args.samples} must be in [2, 100000]")
    seeded = args.perturb in ("mode", "mode_front")
    eigen = _eigenmode(args, pulse, params, required=seeded)
    try:
        spec = DomainSpec(dx=dx, ahead=args.ahead, behind=args.behind)
        rule = TimeStepRule(kind="adaptive", xi_stab=args.xi_stab)
        run = VerifySettings(rule=rule, far_field=args.far_field, n_samples=args.samples,
                             perturbation=(args.perturb, args.eps) if seeded else None,
                             device=args.device)
        res = verify_pulse(pulse, params, args.distance, spec, run,
                           progress=not args.no_progress, eigen=eigen)
    except ParameterError as exc:
        raise UsageError(str(exc))
    write_result(out, res, params, source=os.path.abspath(args.steady), label=label,
                 steady_converged=pulse.converged)
    png = os.path.splitext(out)[0] + ".png"
    plot_verify_result(png, res, pulse, params)
    print(_unconverged_prefix(pulse) + summary(res) + f"; output {out}, figure {png}")
    return 0 if res.info["status"] == "finished" else 2


def cmd_seed(args) -> int:
    """``slippulse dynamic seed``: seed, write the t = 0 state, print the stress mismatch."""
    from ..core.h5io import SchemaError, read_pulse
    from ..core.params import ParameterError
    from ..timedomain.seeding import DomainSpec, seed_pulse, write_seed

    try:
        pulse, params = read_pulse(args.steady, args.label)
    except SchemaError as exc:
        raise UsageError(str(exc))
    _require_converged(args, pulse)
    params = params_for_input(args, params, args.steady)
    out = f"seed_{pulse.label}.h5" if args.out is None else args.out
    check_writable(out, "--out")
    check_distinct(out, "--out", **{"--steady": args.steady, "--mode-file": args.mode_file})
    if os.path.exists(out) and not args.overwrite:
        raise UsageError(f"output file {out} exists: use --overwrite or another --out")
    check_writable(out, "--out")
    from ..timedomain.seeding import default_dx
    dx = default_dx(params) if args.dx is None else args.dx
    _check_grid(dx, args.ahead, args.behind, pulse.L)
    seeded = args.perturb in ("mode", "mode_front")
    eigen = _eigenmode(args, pulse, params, required=True) if seeded else None
    try:
        seed = seed_pulse(pulse, params, DomainSpec(dx=dx, ahead=args.ahead,
                                                    behind=args.behind),
                          far_field=args.far_field)
        if eigen is not None:
            from ..timedomain.eigenmode import perturb_along_mode
            perturb_along_mode(seed, eigen, args.eps,
                               frame="front" if args.perturb == "mode_front" else "lab")
    except ParameterError as exc:
        raise UsageError(str(exc))
    mis = write_seed(out, seed, source=os.path.abspath(args.steady), label=pulse.label)
    if eigen is not None:
        from ..core.h5io import atomic_update

        def fill(h5):
            h5.attrs["perturbation"], h5.attrs["eps"] = args.perturb, float(args.eps)
            h5.attrs["eigen_s_per_L"], h5.attrs["eigen_sigma"] = eigen.s_per_L, eigen.sigma.real
            h5.attrs["eigen_source"] = eigen.source
        atomic_update(out, fill)
    st = seed.stepper
    print(_unconverged_prefix(pulse) + f"seed {pulse.label}: N={st.n}, dx={st.dx * 1e3:.3g} mm, domain {st.length:.4g} m "
          f"({args.behind:g} L behind + {args.ahead:g} L ahead); t = 0 stress vs steady: "
          f"{mis['stress']:.2e} tau_d over the pulse, {mis['stress_all']:.2e} anywhere; "
          f"friction imbalance {mis['friction']:.2e} tau_d"
          + (f"; perturbed by eps = {args.eps:g} x the unstable mode (s = {eigen.s_per_L:.5g} "
             f"per L, {eigen.source})" if eigen is not None else "") + f"; output {out}")
    return 0
