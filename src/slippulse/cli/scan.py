"""``slippulse dynamic scan SCAN.toml [--workers N | --scheduler ADDRESS] [--dry-run] ...``.

Runs the independent simulations of a scan (format and design: :mod:`slippulse.timedomain.scan`) on
the shared executor (:mod:`slippulse.core.executor`: this process, a local Dask cluster, or a Dask
scheduler), reusing the cases already finished, with a progress bar over the cases and a one-line
summary at the end. Exit codes: 0 all cases fine, 1 some case
(or the runner's figures) failed, 2 bad input.
"""
from __future__ import annotations

import os
import sys

from ..core.executor import add_executor_options, settings_from_args
from ..core.params import ParameterError
from .paramargs import add_params_args, check_files


def register(sub) -> None:
    """Add ``scan`` and ``pack`` to the ``slippulse dynamic`` sub-commands ``sub``."""
    p = sub.add_parser(
        "scan", help="run the independent simulations of a scan (SCAN.toml), resumable",
        description="Run every case of SCAN.toml (cartesian product of [grid] over [defaults], "
                    "then the [[case]] tables) through the scan's runner, one HDF5 file per case "
                    "in scan.out_dir; finished cases are reused. Writes summary.csv and summary.h5 "
                    "in scan.out_dir. SCAN.toml holds a [scan] table (name, out_dir, optionally "
                    "runner = \"module:function\"), [defaults] (values shared by every case), "
                    "[grid] (lists whose cartesian product gives cases) and [[case]] tables "
                    "(extra cases); values are scalars. Example: dynamic/scans/example.toml.")
    p.add_argument("scan", metavar="SCAN.toml", help="scan description (TOML)")
    add_executor_options(p, "cases")
    p.add_argument("--overwrite", action="store_true",
                   help="rerun cases whose output file holds another case (default: refuse)")
    p.add_argument("--dry-run", action="store_true",
                   help="list the cases (id, state, output file) and exit")
    p.add_argument("--no-progress", action="store_true", help="do not show the progress bar")
    add_params_args(p)
    p.set_defaults(func=cmd_scan)
    k = sub.add_parser("pack", help="pack a scan's results small (no slip-rate snapshots, no figures)",
                       description="Write SCAN_DIR as a gzipped tar OUT: each case file with its "
                                   "attributes and groups but of its snapshots only the times "
                                   "and front positions; summaries and tables as they are; no "
                                   "figures. For carrying a scan off a lent machine.")
    k.add_argument("scan_dir", metavar="SCAN_DIR", help="the scan's output directory")
    k.add_argument("out", metavar="OUT", help="the .tar.gz to write")
    k.set_defaults(func=cmd_pack)


def cmd_pack(args) -> int:
    from ..core.h5io import check_writable
    from ..timedomain.scan import pack_scan
    check_writable(args.out, "OUT")
    n, size = pack_scan(args.scan_dir, args.out)
    print(f"packed {n} files of {_show(args.scan_dir)} -> {args.out} ({size} bytes)")
    return 0


_STATE = {"done": "done", "missing": "todo", "incomplete": "todo (incomplete file)",
          "other": "CLASH (file holds another case; --overwrite)"}


def _show(path: str) -> str:
    rel = os.path.relpath(path)
    return path if rel.startswith("..") else rel


def _figures_hook(scan):
    """The perturbation runner's figures (pair table + plots) live in the plotting layer; other
    runners bring their own ``scan_figures`` (None here: run_scan looks it up)."""
    from ..timedomain import perturbation
    from ..timedomain.scan import load_runner

    if load_runner(scan.runner, scan.runner_path)[0] is perturbation.run_case:
        from ..plotting.stability import scan_figures
        return scan_figures
    return None


def _check_cases(scan) -> list[dict] | None:
    """Perturbation scans: every case's keys and values (``perturbation.check_case``), a bad one
    named (exit 2); the resolved cases, or None for another runner. Its files need not exist yet
    (a dry run lists the cases; a real run checks them, :func:`_check_steady_pulses`)."""
    from ..timedomain import perturbation
    from ..timedomain.scan import load_runner

    if load_runner(scan.runner, scan.runner_path)[0] is not perturbation.run_case:
        return None
    resolved = []
    for case in scan.cases:
        try:
            resolved.append(perturbation.check_case(case.params))
        except ParameterError as exc:
            raise ParameterError(f"case {case.id}: {exc}") from None
    return resolved


def _check_steady_pulses(scan) -> None:
    """Perturbation scans: every case valid (:func:`_check_cases`) and its steady pulse marked
    converged (the same ``h5io.require_converged`` as the other readers), checked before any
    case runs (exit 2)."""
    from ..core.h5io import require_converged

    cases = _check_cases(scan)
    if cases is None:
        return
    for path, label in sorted({(c["steady"], c["label"]) for c in cases}):
        require_converged(path, [label])


def cmd_scan(args) -> int:
    from ..timedomain.scan import load_scan, run_scan, scan_states

    scan = load_scan(args.scan)
    # the cases' pulses keep the parameters they were solved with: given ones must agree
    check_files(args, [c.params["steady"] for c in scan.cases if "steady" in c.params])
    if args.dry_run:
        _check_cases(scan)
        states = scan_states(scan)
        width = max(len(c.id) for c in scan.cases)
        print(f"scan {scan.name}: {len(scan.cases)} cases, runner {scan.runner}, "
              f"out_dir {_show(scan.out_dir)}")
        for c, s in zip(scan.cases, states):
            print(f"  {c.id:<{width}}  {_STATE[s]:<6}  {_show(scan.out_file(c))}")
        print(f"{states.count('done')} done, {len(states) - states.count('done')} to run")
        return 0
    executor = settings_from_args(args)
    _check_steady_pulses(scan)
    from .checks import check_outdir
    check_outdir(scan.out_dir, "scan.out_dir")
    import signal

    def _terminate(signum, frame):          # a kill stops the workers too (TaskPool's exit)
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, _terminate)
    try:
        res = run_scan(scan, executor=executor, overwrite=args.overwrite,
                       progress=not args.no_progress, figures=_figures_hook(scan))
    finally:
        signal.signal(signal.SIGTERM, old)
    for row in res.rows:
        if str(row["status"]).startswith("error"):
            print(f"scan {scan.name}: case {row['id']}: {row['status']}", file=sys.stderr)
    if res.figure_error:
        print(f"scan {scan.name}: scan_figures failed: {res.figure_error}", file=sys.stderr)
    elif res.figures:
        print(f"scan {scan.name}: figures: {', '.join(_show(f) for f in res.figures)}")
    print(res.line(), file=sys.stdout if res.ok else sys.stderr)
    return 0 if res.ok else 1
