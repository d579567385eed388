"""``slippulse steady analyse``: analyse a family file, store the results in it, print the table."""
from __future__ import annotations

import math

from ..core import h5io
from ..core.params import ParameterError
from ..steady import analysis


#: the default c_d/c_s of the mode-II mapping (``steady.modeii``), as the help states them
CD_CS_DEFAULTS = ("1.6, sqrt(3) and 2, the P-to-S wave speed ratios of solids of Poisson's ratio "
                  "0.18, 1/4 and 1/3")


def check_cd_over_cs(values):
    """c_d/c_s values of the mode-II mapping from the command line (None: the default set),
    each a finite number > 1; else ParameterError naming ``cd-cs``."""
    if values is None:
        return None
    for v in values:
        if not (math.isfinite(v) and v > 1.0):
            raise ParameterError(f"cd-cs={v!r} is invalid: c_d/c_s must be a finite number > 1 "
                                 "(sqrt(3) for a Poisson solid)")
    return tuple(float(v) for v in values)


def cmd_analyse(args):
    """CLI action for ``slippulse steady analyse FILE [--no-write]`` (argparse namespace with
    ``file`` and optional ``no_write``): analyse, store the results in FILE, print the table."""
    h5io.check_pulses(args.file, "FILE")       # every pulse valid, before any work
    cd = check_cd_over_cs(getattr(args, "cd_cs", None))
    skip = h5io.require_converged(args.file, allow=getattr(args, "skip_unconverged", False),
                                  hint="--skip-unconverged leaves them out")
    write = not getattr(args, "no_write", False)
    if write:
        h5io.check_writable(args.file, "FILE")
    rows = analysis.analyse_family(args.file, write=write, skip=skip, cd_over_cs=cd)
    print(analysis.format_table(rows))
    return 0
