"""``slippulse figures FILE [--outdir runs/figures]``: the paper's figures from a family file."""
from __future__ import annotations

import os

from .analyse import CD_CS_DEFAULTS
from .app import UsageError
from .paramargs import add_params_args, check_files


def register(subparsers):
    p = subparsers.add_parser(
        "figures", help="regenerate Figs. 1-4 and S1-S4 of the paper from a family file",
        description="Regenerate Figs. 1, 2, 3, 4 and S1-S4 (PNG and PDF) from a family HDF5 file "
                    "(pulses/tdX.XXXX groups). Prints the analysis table.")
    p.add_argument("file", metavar="FILE", help="family HDF5 file")
    p.add_argument("--outdir", default=os.path.join("runs", "figures"),
                   help="output directory (default: runs/figures)")
    p.add_argument("--compare", metavar="FILE2", default=None,
                   help="second family file (another domain size) for Fig. S1(b)")
    p.add_argument("--formats", default="png,pdf", help="comma-separated formats (default png,pdf)")
    p.add_argument("--cd-cs", type=float, nargs="+", default=None, metavar="RATIO",
                   help=f"c_d/c_s of the mode-II figure S4 (default {CD_CS_DEFAULTS}); each > 1")
    p.add_argument("--skip-unconverged", action="store_true",
                   help="leave out the pulses marked converged=False (default: refuse the file)")
    add_params_args(p)
    p.set_defaults(func=run)


def run(args):
    from ..steady import analysis
    from .analyse import check_cd_over_cs
    from ..plotting import steady as plotting

    from ..core.h5io import check_pulses
    for f, what in [(args.file, "FILE")] + ([(args.compare, "--compare")] if args.compare else []):
        check_pulses(f, what)                 # every pulse valid, before any work
    formats = tuple(s.strip() for s in args.formats.split(",") if s.strip())
    bad = [f for f in formats if f not in ("png", "pdf", "svg")]
    if bad or not formats:
        raise UsageError(f"--formats={args.formats!r}: choose from png, pdf, svg")
    skip = _unconverged(args)
    check_files(args, [args.file] + ([args.compare] if args.compare else []))
    cd = check_cd_over_cs(args.cd_cs)
    from .checks import check_outdir
    check_outdir(args.outdir, "--outdir")
    data = plotting.load_family(args.file, compare_path=args.compare, cd_over_cs=cd, skip=skip)
    if skip:
        print(f"left out (marked converged=False): {', '.join(skip)}")
    written = plotting.save_all(data, args.outdir, formats=formats)
    print(analysis.format_table(data.rows))
    print(f"wrote {len(written)} files to {args.outdir}")
    return 0


def _unconverged(args) -> list:
    """The unconverged pulses of FILE (refused unless --skip-unconverged; those of --compare are
    always left out of Fig. S1b)."""
    from ..core.h5io import require_converged
    hint = "--skip-unconverged leaves them out"
    if args.compare:
        require_converged(args.compare, allow=args.skip_unconverged, hint=hint)
    return require_converged(args.file, allow=args.skip_unconverged, hint=hint)
