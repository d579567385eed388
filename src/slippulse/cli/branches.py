"""``slippulse steady branches`` (every pulse at one τ_d, by deflated Newton), ``slippulse steady
branch-trace`` (one branch by pseudo-arclength, its pulses written) and ``slippulse steady
bifurcations`` (fold and branch-point test functions along a family file); ``steady branch-map``
(cli/branch_map.py) is registered from here."""
from __future__ import annotations

import math
import os
import sys

from tqdm import tqdm

from ..core.errors import UsageError
from ..core.params import ParameterError
from .checks import check_labels
from .paramargs import add_params_args, params_for_input, params_for_output


def cmd_bifurcations(args) -> int:
    from ..core.h5io import open_h5, read_parameters
    from ..steady.bifurcation import scan

    if not 0 <= args.modes <= 6:
        raise UsageError(f"--modes={args.modes} is invalid: must be in [0, 6]")
    with open_h5(args.file, "FILE") as h5:
        stored = read_parameters(h5)
    params_for_input(args, stored, args.file)
    labels = check_labels(args.file, args.labels or [])
    if args.labels:
        labels = args.labels
    bar = tqdm(total=len(labels), desc="test functions", unit="pulse", disable=args.quiet,
               file=sys.stderr)

    def progress(row):
        bar.set_postfix_str(f"{row.label} sigma1={row.values.sigma[0]:.2e}")
        bar.update(1)

    rows, evs = scan(args.file, order=args.order, labels=labels, progress=progress)
    bar.close()
    print("label tau_d/tau_min beta L(m) N sign(detA) ln|detA| sign(detB) t_q sigma1 sigma2 "
          "max|r| n_unstable_real")
    for r in rows:
        v = r.values
        cnt = "-" if r.unstable_count is None else str(r.unstable_count)
        print(f"{r.label} {r.tau_d_ratio:.7f} {r.beta:.7g} {r.L:.6g} {r.n_points} "
              f"{v.fold_sign:+d} {v.fold_logdet:.6g} {v.bordered_sign:+d} {v.t_param:+.4e} "
              f"{v.sigma[0]:.4e} {v.sigma[1]:.4e} {r.max_residual:.1e} {cnt}")
    if args.modes:
        from ..core.h5io import read_pulse
        from ..steady.bifurcation import pulse_null_modes
        print(f"the {args.modes} smallest singular values of A and the shift each right singular "
              "vector is (cosine with d ln v/dxi of the whole pulse, its front hump or the humps "
              "behind it; 'other' below 0.9)")
        for r in rows:
            modes = pulse_null_modes(read_pulse(args.file, r.label)[0], stored, args.modes)
            print(f"{r.label} " + "; ".join(m.describe() for m in modes))
    if args.write:
        from ..steady.bifurcation import write_indicators
        write_indicators(args.file, rows)
    for line in event_lines(args.file, stored, rows, evs, locate=args.locate):
        print(line)
    return 0


def event_lines(path, params, rows, evs, locate=True, bridge=True) -> list[str]:
    """The lines that report the test functions' events along the pulses ``rows`` of ``path``
    (:func:`~slippulse.steady.bifurcation.events`), each fold and branch point located between
    its two pulses when ``locate``, each sign change of det B across a change of N that the
    family run did not decide decided on one grid when ``locate`` and ``bridge``, and the count
    line (folds, branch points, those sign changes, σ₁/σ₂ minima, the smallest σ₁)."""
    from ..core.h5io import read_pulse
    from ..steady.bifurcation import LocateError, across_grid_change, locate_between_pulses
    lines = [f"event: {e.kind} between {e.between[0]} and {e.between[1]}: {e.detail}" for e in evs]
    kept = sum(r.across == "kept" for r in rows)     # decided when the family wrote them
    undecided = jumps = 0
    found = []                                       # branch points found across a grid change
    for e in evs:
        if e.kind == "not comparable":
            if not (locate and bridge):
                undecided += 1
                continue
        elif not locate or e.kind not in ("fold", "branch point"):
            continue
        pa, _ = read_pulse(path, e.between[0])
        pb, _ = read_pulse(path, e.between[1])
        if e.kind == "not comparable":
            try:
                bp = across_grid_change(pa, pb, params)
            except LocateError as exc:
                lines.append(f"across the grid change {e.between}: not decided ({exc})")
                undecided += 1
                continue
            lines.append(f"across the grid change {e.between}: " + (
                f"BRANCH POINT ({bp.detail})" if bp else
                "the same sign of det B on one grid: no branch point between them"))
            if bp is None:
                kept += 1
                continue
            found.append(bp)
        if pa.n_points < pb.n_points:              # locate on the finer grid
            pa, pb = pb, pa
        try:
            b = locate_between_pulses(pa, pb, params)
            if b.jump:
                lines.append(f"located: no {b.kind} between {e.between}: the test function "
                             f"changes sign by a jump at tau_d/tau_min={b.extra['tau_d_ratio']:.9f} "
                             f"(|test| {abs(b.residual_test):.2g} of its value at the first "
                             "pulse, no zero): the two pulses lie on nearby different solution "
                             f"branches; smallest mode of A there {b.extra['null_mode']}")
                jumps += 1
                continue
            lines.append(f"located: {b.kind} at tau_d/tau_min={b.extra['tau_d_ratio']:.9f} "
                         f"beta={b.extra['beta']:.8g} L={b.extra['L']:.6g} m; "
                         f"cos(psi, dF/dq)={b.extra['transversality']:.3e} (0 at a branch "
                         f"point), smallest mode of A {b.extra['null_mode']} "
                         f"({b.evaluations} evaluations"
                         f"{'' if b.converged else ', NOT CONVERGED: bracket still open, best point shown'})")
        except LocateError as exc:
            lines.append(f"located: {e.kind} between {e.between}: not located ({exc})")
    count = {k: sum(e.kind == k for e in evs + found)
             for k in ("fold", "branch point", "not comparable", "sigma minimum")}
    sig = [r.values.sigma[0] for r in rows if r.values.sigma]
    smin = f"{min(sig):.3e}" if sig else "not computed"
    lines.append(f"{len(rows)} pulses: {count['fold']} folds (t_q sign changes), "
                 f"{count['branch point']} branch points (det B sign changes on one grid), "
                 f"{kept} det B sign changes across a change of N that keep the sign on one "
                 f"grid, {undecided} not decided"
                 + (f", {jumps} of them located as jumps between branches, not zeros"
                    if jumps else "")
                 + ("" if not undecided or (locate and bridge) else
                    f" (slippulse steady bifurcations {path} --locate)")
                 + f", {count['sigma minimum']} sigma1/sigma2 minima; smallest sigma1 = "
                 f"{smin}; the test functions have no uncertainty estimate (their signs are exact "
                 "for the discrete system)")
    return lines


def _guess_arg(text: str, params_cli, args):
    """A --guess FILE:LABEL, checked before any work: the file readable, the label in it, its
    parameters those of the run."""
    from ..core.h5io import list_pulses, open_h5, read_parameters, SchemaError
    if ":" not in text:
        raise UsageError(f"guess={text!r} is invalid: must be FILE:LABEL (e.g. family.h5:td1.2000)")
    path, label = text.rsplit(":", 1)
    with open_h5(path, "guess") as h5:
        stored = read_parameters(h5)
    labels = list_pulses(path)
    if label not in labels:
        raise SchemaError(f"guess={text!r}: no pulse label={label!r} in {path}; present: "
                          f"{labels[:6]}{' ...' if len(labels) > 6 else ''}")
    from ..core.params import differing, describe_difference
    if differing(stored, params_cli):
        raise ParameterError(f"guess={text!r}: {path} holds pulses of other parameters: "
                             f"{describe_difference(stored, params_cli, 'in the file', 'given')}")


def solution_label(tau_d_ratio: float, k: int) -> str:
    """Label of the k-th distinct solution at one τ_d: ``pulse_label`` for the first, then the
    same number with 4 + k decimals (td1.2000, td1.20000, td1.200000, ...: every reader parses
    them to the same τ_d)."""
    from ..core.h5io import pulse_label
    if k == 0:
        return pulse_label(tau_d_ratio)
    dec = max(4, len(pulse_label(tau_d_ratio).split(".")[1])) + k
    return f"td{tau_d_ratio:.{dec}f}"


def cmd_branches(args) -> int:
    from ..core.h5io import check_writable, write_pulses
    from ..steady.branch_search import GUESS_SETS, Guess, search

    out = args.out
    params = params_for_output(args, out)
    try:
        q = float(args.tau_d)
    except ValueError:
        raise ParameterError(f"tau-d={args.tau_d!r} is invalid: must be a number (tau_d/tau_min) "
                             f"in (1, {params.tau_peak / params.tau_min:.5f})") from None
    if not (math.isfinite(q) and 1.0 < q < params.tau_peak / params.tau_min):
        raise ParameterError(f"tau-d={args.tau_d} is invalid: must be in (1, "
                             f"{params.tau_peak / params.tau_min:.5f}) (tau_min < tau_d < the "
                             "local maximum of tau_ss)")
    if not (args.p >= 1 and math.isfinite(args.p)):
        raise ParameterError(f"p={args.p!r} is invalid: the deflation power must be >= 1")
    if not (args.sigma >= 0 and math.isfinite(args.sigma)):
        raise ParameterError(f"sigma={args.sigma!r} is invalid: the deflation shift must be >= 0")
    from ..steady.solver import check_points
    check_points(args.points)
    check_points(args.coarse_points)
    if args.max_solutions < 1:
        raise ParameterError(f"max-solutions={args.max_solutions} is invalid: must be >= 1")
    check_writable(out, "out")
    if os.path.exists(out) and not args.overwrite:
        raise UsageError(f"out={out!r} exists; --overwrite replaces it")
    for g in args.guess:
        _guess_arg(g, params, args)
    guesses = ([] if args.guesses == "none" else GUESS_SETS[args.guesses]())
    guesses += [Guess(source=g) for g in args.guess]
    if not guesses:
        raise UsageError("no guesses: --guesses none needs at least one --guess FILE:LABEL")
    bar = tqdm(total=len(guesses), desc=f"branches {q:g}", unit="guess", disable=args.quiet,
               file=sys.stderr)

    def progress(msg):
        g = int(msg.split(":")[0].split()[1])
        bar.n = g
        bar.set_postfix_str(msg[:60])

    rep = search(params, q, guesses, n_points=args.points, coarse_points=args.coarse_points,
                 p=args.p, sigma=args.sigma, max_solutions=args.max_solutions,
                 check=not args.no_grid_check, progress=progress)
    bar.n = len(guesses)
    bar.close()
    for gi, g in enumerate(guesses):
        got = ", ".join(str(i) for i in rep.reached[gi]) or "none"
        print(f"guess {gi} ({g.describe(params)}): reached {got}; "
              f"{'; '.join(rep.attempts[gi])}")
    if not rep.found:
        print(f"slippulse: no pulse converged at tau_d/tau_min={q:g} from {len(guesses)} guesses; "
              f"nothing written to {out}", file=sys.stderr)
        return 1
    for k, f in enumerate(rep.found):
        p = f.pulse
        p.name = solution_label(q, k)
        p.extra.update({
            "branch_index": k, "guess_index": int(f.guess),
            "guess": guesses[f.guess].describe(params),
            "reached_by": ",".join(str(gi) for gi, r in enumerate(rep.reached) if k in r),
            "deflation": f"p={args.p:g} sigma={args.sigma:g} norm=sqrt(mean(dlnv^2)+"
                         "(dbeta/beta)^2)",
            "grid_check_passed": bool(f.check.get("passed", False)),
            "grid_check_n_fine": int(f.check.get("n_fine", 0)),
            "grid_check_dbeta": float(f.check.get("dbeta", math.nan)),
            "grid_check_dL_rel": float(f.check.get("dL_rel", math.nan))})
    write_pulses(out, [f.pulse for f in rep.found], params, replace=True)
    for k, f in enumerate(rep.found):
        p, c = f.pulse, f.check
        chk = (f"grid check N={p.n_points}->{c['n_fine']}: dbeta={c['dbeta']:.1e} "
               f"dL/L={c['dL_rel']:.1e}" if c.get("passed") else
               f"grid check {'failed: ' + c.get('message', '') if c else 'not run'}")
        print(f"solution {k} [{solution_label(q, k)}]: beta={p.beta:.8g} L={p.L:.6g} m "
              f"humps={p.extra['n_humps']} max|D|={p.max_residual:.1e} N={p.n_points}; {chk}")
    print(f"{len(rep.found)} distinct pulses at tau_d/tau_min={q:g} from {len(guesses)} guesses "
          f"(deflation p={args.p:g}, sigma={args.sigma:g}; norm: RMS of ln v over the nodes with "
          f"the relative speed), written to {out}; wall={rep.wall_time:.1f} s. Distinct means "
          "farther apart than 0.05 in that norm; solutions no guess reached are not excluded")
    return 0


def cmd_branch_trace(args) -> int:
    """Trace the branch of a stored pulse by pseudo-arclength and write its pulses as they come."""
    from ..core.h5io import check_writable

    if ":" not in args.source:
        raise UsageError(f"source={args.source!r} is invalid: must be FILE:LABEL "
                         "(e.g. branches.h5:td1.20000)")
    path, label = args.source.rsplit(":", 1)
    from ..core.h5io import (label_ratio, list_pulses, open_h5, read_parameters, read_pulse,
                             SchemaError)
    with open_h5(path, "source") as h5:
        stored = read_parameters(h5)
    params_for_input(args, stored, path)
    if label not in list_pulses(path):
        raise SchemaError(f"source={args.source!r}: no pulse label={label!r} in {path}")
    params = stored
    for name, lo in (("ds", 0.0), ("ds_min", 0.0), ("ds_max", 0.0)):
        val = getattr(args, name)
        if not (math.isfinite(val) and val > lo):
            raise ParameterError(f"{name.replace('_', '-')}={val!r} is invalid: must be > 0")
    if not args.ds_min <= args.ds <= args.ds_max:
        raise ParameterError(f"ds={args.ds:g} is invalid: must lie in [ds-min, ds-max] = "
                             f"[{args.ds_min:g}, {args.ds_max:g}]")
    if args.max_steps < 1 or args.every < 1:
        raise ParameterError("max-steps and every must be integers >= 1")
    if not (math.isfinite(args.regrid) and args.regrid > 0):
        raise ParameterError(f"regrid={args.regrid!r} is invalid: must be > 0 (a fraction of L)")
    if args.points is not None and args.points < 10:
        raise ParameterError(f"points={args.points!r} is invalid: must be >= 10")
    if not (math.isfinite(args.arc_state) and args.arc_state >= 0):
        raise ParameterError(f"arc-state={args.arc_state!r} is invalid: must be a finite "
                             "number >= 0")
    out = args.out
    check_writable(out, "out")
    if os.path.exists(out) and args.overwrite:
        os.remove(out)
    ends = _trace_ends(out, args) if os.path.exists(out) else {}
    pulse, _ = read_pulse(path, label)
    taken = {lab: label_ratio(lab) for lab in (list_pulses(out) if ends else [])}
    written = []
    dirs = {"down": ["down"], "up": ["up"], "both": ["down", "up"]}[args.direction]
    for n_dir, name in enumerate(dirs):
        rc = _trace_one(args, params, pulse, name, out, taken, written,
                        skip_start=n_dir > 0 or bool(ends),
                        resume=ends.get(name))
        if rc:
            return rc
    return 0


def _trace_ends(out, args) -> dict:
    """The last written pulse of each direction of the trace stored in ``out``, which this
    command resumes: {direction: pulse}. Refused (one line) where ``out`` holds anything else
    than this command's trace: another start pulse, another arclength metric, or no trace."""
    from ..core.h5io import list_pulses, read_pulse
    from ..steady.branch_trace import ArcMetric
    want = {"trace_source": args.source, "trace_arc_metric": ArcMetric(args.arc_state).describe()}
    ends = {}
    for lab in list_pulses(out):
        p = read_pulse(out, lab)[0]
        have = {k: p.extra.get(k) for k in want}
        if have != want:
            raise UsageError(f"out={out!r} holds another trace ({have['trace_source']!r}, "
                             f"metric {have['trace_arc_metric']!r}), not this one "
                             f"({args.source!r}, metric {want['trace_arc_metric']!r}); "
                             "--overwrite replaces it")
        try:
            name = str(p.extra["trace_direction"])
            for key in ("trace_step", "trace_grid"):
                p.extra[key] = int(p.extra[key])
            p.extra["trace_t_q"] = float(p.extra["trace_t_q"])
        except (KeyError, TypeError, ValueError):
            raise UsageError(f"out={out!r}: pulse {lab!r} lacks its trace attributes (trace_"
                             "direction, _step, _grid, _t_q), so the trace cannot be resumed; "
                             "--overwrite replaces it") from None
        if name not in ("down", "up"):
            raise UsageError(f"out={out!r}: pulse {lab!r} has trace_direction={name!r}, not "
                             "'down' or 'up'; --overwrite replaces it")
        if name not in ends or p.extra["trace_step"] > ends[name].extra["trace_step"]:
            ends[name] = p
    return ends


def _trace_one(args, params, pulse, name, out, taken, written, skip_start, resume=None) -> int:
    """One direction of ``steady branch-trace``: trace, write, print. ``skip_start``: the start
    pulse is already written (by the other direction, or by the run resumed). ``resume``: the
    last pulse this direction wrote before (the march goes on from it along its stored t_q,
    steps numbered on; a direction the branch itself stopped is not retraced)."""
    from ..core.h5io import unique_label, write_pulse
    from ..steady.branch_trace import ArcMetric, TraceSettings, check_on_normal, trace
    from ..steady.continuation.tolerance import GRID_TOLERANCE
    position_sign = -1 if name == "down" else 1
    direction = position_sign
    metric = ArcMetric(args.arc_state)
    k0 = grid0 = 0
    if resume is not None:
        k0, grid0 = resume.extra["trace_step"], resume.extra["trace_grid"]   # ints (_trace_ends)
        if resume.extra.get("trace_stop_reason"):
            print(f"trace {name}: already ended at step {k0} ({resume.label}): "
                  f"{resume.extra['trace_stop_reason']}")
            return 0
        if k0 >= args.max_steps:
            print(f"trace {name}: max-steps={args.max_steps} already reached (step {k0}, "
                  f"{resume.label}); a larger --max-steps goes on")
            return 0
        print(f"resumed trace {name} from step {k0} ({resume.label}) in {out}", file=sys.stderr)
        pulse, skip_start = resume, True
        direction = 1 if resume.extra["trace_t_q"] > 0 else -1   # the march's own orientation
    mine = []
    bar = tqdm(total=args.max_steps + 1, initial=k0, desc=f"trace {name}", unit="step",
               disable=args.quiet, file=sys.stderr)

    def on_pulse(pt, p):
        k = k0 + len(bar_steps)
        bar_steps.append(pt)
        bar.update(1)
        bar.set_postfix_str(f"q={pt.q:.6f} beta={pt.beta:.4g} L={pt.L:.4g}")
        if (k % args.every and k != k0) or (k == k0 and skip_start):
            return
        write(k, pt, p)

    def write(k, pt, p):
        p.name = unique_label(p.tau_d_ratio, taken)
        taken[p.name] = p.tau_d_ratio
        p.extra.update({"trace_source": args.source, "trace_direction": name,
                        "trace_step": int(k), "trace_position": int(k * position_sign),
                        "trace_t_q": float(pt.t_q),
                        "trace_fold_sign": int(pt.fold_sign),
                        "trace_bordered_sign": int(pt.bordered_sign),
                        "trace_grid": int(pt.grid) + grid0, "trace_extent": float(pt.extent),
                        "trace_arc_metric": metric.describe()})
        if args.grid_check:
            c = check_on_normal(params, p, metric)
            ok = bool(c.get("passed")) and GRID_TOLERANCE.passes(c["dbeta"], c["dL_rel"])
            p.extra.update({"grid_check_converged": bool(c.get("passed", False)),
                            "grid_check_passed": ok,
                            "grid_check_n_fine": int(c.get("n_fine", 0)),
                            "grid_check_dbeta": float(c.get("dbeta", math.nan)),
                            "grid_check_dq": float(c.get("dq", math.nan)),
                            "grid_check_dL_rel": float(c.get("dL_rel", math.nan)),
                            "grid_check_method": "nested 2N-1 on the hyperplane normal to the "
                                                 "branch in the trace's metric"})
        write_pulse(out, p, params)
        written.append((k, pt, p))
        mine.append((k, pt, p))

    bar_steps = []
    try:
        settings = TraceSettings(direction=direction, ds=args.ds, ds_min=args.ds_min,
                                 ds_max=args.ds_max, max_steps=args.max_steps - k0,
                                 n_points=args.points, regrid=args.regrid,
                                 relay_start=args.relay and resume is None, metric=metric)
        tr = trace(params, pulse, settings, on_pulse=on_pulse)
    except RuntimeError as exc:        # the start pulse's re-lay, or a tangent with no (β, q) part
        bar.close()
        print(f"slippulse: trace {name} from {args.source} failed: {exc}; "
              f"{len(written)} pulses written to {out}", file=sys.stderr)
        return 1
    bar.close()
    last = k0 + len(bar_steps) - 1
    if not tr.out_of_steps:            # the branch stopped it: a rerun does not retrace it
        tr.pulses[-1].extra["trace_stop_reason"] = tr.stop_reason
    if (not mine or mine[-1][0] != last) and len(bar_steps) > 1:          # the last point
        write(last, tr.points[-1], tr.pulses[-1])
    elif not tr.out_of_steps:          # the last point is stored: its label, with the reason
        p_last = mine[-1][2] if mine and mine[-1][0] == last else resume
        if p_last is not None:
            p_last.extra["trace_stop_reason"] = tr.stop_reason
            write_pulse(out, p_last, params)
    _report_trace(args, name, tr, mine, metric, out)
    return 0


def _report_trace(args, name, tr, mine, metric, out) -> None:
    """Print one direction's written points, its events and its one-line summary."""
    from ..steady.continuation.tolerance import GRID_TOLERANCE
    print(f"trace {name}: step label tau_d/tau_min beta L(m) extent(m) humps N sign(detA) t_q "
          "sign(detB) grid grid_check(dbeta dq dL/L passed)")
    for k, pt, p in mine:
        gc = ("-" if not args.grid_check else
              f"{p.extra['grid_check_dbeta']:.1e} {p.extra['grid_check_dq']:.1e} "
              f"{p.extra['grid_check_dL_rel']:.1e} "
              f"{'yes' if p.extra['grid_check_passed'] else 'NO'}")
        print(f"{k} {p.label} {pt.q:.7f} {pt.beta:.8g} {pt.L:.6g} {pt.extent:.4g} {pt.humps} "
              f"{pt.n_points} "
              f"{pt.fold_sign:+d} {pt.t_q:+.3e} {pt.bordered_sign:+d} {pt.grid} {gc}")
    for kind, i, detail in tr.events:
        print(f"event ({name}): {kind} at step {i}: {detail}")
    n_pass = sum(bool(p.extra.get("grid_check_passed")) for _, _, p in mine)
    print(f"{len(tr.points)} points traced {name} from {args.source} by the arclength in "
          f"{metric.describe()} "
          f"(q {tr.points[0].q:.6f} -> {tr.points[-1].q:.6f}), {len(mine)} written to {out}"
          + (f", {n_pass} pass the grid check (|dbeta| <= {GRID_TOLERANCE.beta:g}, "
             f"|dL/L| <= {GRID_TOLERANCE.L:g} at 2N-1)" if args.grid_check else
             ", not grid-checked")
          + f"; stopped: {tr.stop_reason}; wall={tr.wall_time:.1f} s")


def register_steady(ss) -> None:
    """Add ``branches`` and ``bifurcations`` to the ``steady`` sub-parsers."""
    p = ss.add_parser("bifurcations", help="fold and branch-point test functions along a family",
                      description="For every converged pulse of FILE: the sign and ln|det| of the "
                                  "pinned fixed-tau_d Newton matrix A = [F_u F_c] (LU), the "
                                  "tangent's tau_d component t_q, the sign of det B of the "
                                  "bordered matrix B = [J; t^T] and its two smallest singular "
                                  "values (speed column scaled by beta). A sign change of t_q "
                                  "between neighbours is a fold, of det B (equal N) a branch "
                                  "point; --locate finds them by regula falsi on det A or "
                                  "det[J; d] (docs/branches.md).")
    p.add_argument("file", metavar="FILE", help="HDF5 family file")
    p.add_argument("--labels", nargs="+", default=None, metavar="LABEL",
                   help="pulses to examine (default: all converged)")
    p.add_argument("--order", choices=("beta", "file"), default="beta",
                   help="neighbour order: by beta (default; monotone along the main family) or "
                        "by the file's decreasing tau_d")
    p.add_argument("--locate", action="store_true",
                   help="locate each fold or branch point found (re-solves between neighbours)")
    p.add_argument("--modes", type=int, default=0, metavar="K",
                   help="also print the K smallest singular values of A and what each right "
                        "singular vector moves: the whole pulse, its front hump or the humps "
                        "behind it (steady.null_modes; default 0: none)")
    p.add_argument("--write", action="store_true",
                   help="also store them as attributes of each pulse (bif_fold_sign, "
                        "bif_fold_logdet, bif_bordered_sign, bif_t_q, bif_sigma1, bif_sigma2), "
                        "atomically")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    add_params_args(p)
    p.set_defaults(func=cmd_bifurcations)

    p = ss.add_parser("branches", help="every steady pulse at one tau_d, by deflated Newton",
                      description="Deflated Newton (Farrell, Birkisson & Funke 2015) from a stated "
                                  "set of guesses: each solution found is removed from the "
                                  "residual by M(x) = prod (1/||x - x_i||^p + sigma) and Newton "
                                  "restarts from the same guess until it fails. Each distinct "
                                  "pulse is refined to --points, grid-checked at 2N-1 and written "
                                  "to --out (labels tdX.XXXX, tdX.XXXX0, ...) with its beta, L, "
                                  "hump count and check; the guesses and what each reached are "
                                  "printed (docs/branches.md).")
    p.add_argument("--tau-d", required=True, help="driving stress tau_d/tau_min, in (1, 1.3319)")
    p.add_argument("--out", required=True, help="output HDF5 (refused if it exists, unless "
                                                "--overwrite)")
    p.add_argument("--guesses", choices=("basin", "single", "quick", "none"), default="basin",
                   help="built-in guesses: basin (default: 27 Freund pulses of the measured basin "
                        "and 5 two- and three-pulse bound states), single (the 27), quick (the "
                        "built-in guess and one two-pulse state 1.4 m apart), none")
    p.add_argument("--guess", action="append", default=[], metavar="FILE:LABEL",
                   help="also start from a stored pulse (repeatable)")
    p.add_argument("--points", type=int, default=1000, help="grid points N of each solution "
                                                            "(default 1000)")
    p.add_argument("--coarse-points", type=int, default=500,
                   help="points of the guesses' grids, where deflation acts (default 500)")
    p.add_argument("--p", type=float, default=2.0, help="deflation power p (default 2)")
    p.add_argument("--sigma", type=float, default=1.0, help="deflation shift sigma (default 1)")
    p.add_argument("--max-solutions", type=int, default=8, help="stop after this many (default 8)")
    p.add_argument("--no-grid-check", action="store_true", help="skip the 2N-1 re-solves")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    add_params_args(p)
    p.set_defaults(func=cmd_branches)
    _register_branch_trace(ss)

    from .branch_map import register as register_branch_map
    register_branch_map(ss)


def _register_branch_trace(ss) -> None:
    p = ss.add_parser("branch-trace", help="trace the branch of one stored pulse in tau_d",
                      description="Pseudo-arclength in (ln beta, tau_d/tau_min/0.04) from a stored "
                                  "pulse (steady.branch_trace; docs/branches.md section 3), each "
                                  "accepted point written to --out as it comes, with its tangent's "
                                  "tau_d component t_q, sign det A, sign det B and grid index; "
                                  "--grid-check re-solves each written pulse at 2N-1. Prints the "
                                  "points, the events (fold: t_q changes sign; branch point: det B "
                                  "changes sign on one grid; hump count) and why it stopped. "
                                  "Interrupted, the same command again resumes it.")
    p.add_argument("source", metavar="FILE:LABEL", help="the start pulse")
    p.add_argument("--direction", choices=("down", "up", "both"), required=True,
                   help="start toward decreasing (down) or increasing (up) tau_d, or both, one "
                        "after the other, into one file")
    p.add_argument("--out", required=True,
                   help="output HDF5; where it holds this trace (same FILE:LABEL and --arc-state)"
                        " the command resumes it: each direction goes on from its last written "
                        "pulse, up to --max-steps in all, unless the branch ended it; a file of "
                        "anything else is refused unless --overwrite")
    p.add_argument("--ds", type=float, default=0.1, help="first arclength step (default 0.1)")
    p.add_argument("--ds-min", type=float, default=1e-3,
                   help="stop when the step falls below this (default 1e-3)")
    p.add_argument("--ds-max", type=float, default=0.4, help="largest step (default 0.4)")
    p.add_argument("--max-steps", type=int, default=80, help="most steps (default 80)")
    p.add_argument("--points", type=int, default=None,
                   help="N of the re-laid grids (default: the start pulse's)")
    p.add_argument("--regrid", type=float, default=0.25,
                   help="re-lay the grid when L has moved by this fraction (default 0.25)")
    p.add_argument("--arc-state", type=float, default=0.0, metavar="W",
                   help="count the pulse's shape in the arclength: W times the RMS change of "
                        "ln v over the nodes beside (ln beta, q/0.04); follows a branch that "
                        "changes in shape at nearly fixed (beta, tau_d), where the scalars alone "
                        "stall (default 0: the scalars only)")
    p.add_argument("--relay", action="store_true",
                   help="first re-lay the start pulse's grid (adapted, --points) and re-solve it "
                        "(e.g. from the end of a trace whose grid no longer fits the pulse)")
    p.add_argument("--every", type=int, default=1,
                   help="write every k-th point (and the first and last; default 1)")
    p.add_argument("--grid-check", action="store_true",
                   help="re-solve each written pulse at 2N-1 (nested) on the hyperplane normal "
                        "to the branch in the trace's metric (where a fixed-tau_d re-solve fails "
                        "at folds and where the shape moves at nearly fixed tau_d) and store "
                        "dbeta, dq, dL/L and whether dbeta and dL/L meet the family's criterion "
                        "(1e-5, 1e-4)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing --out (start afresh)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    add_params_args(p)
    p.set_defaults(func=cmd_branch_trace)
