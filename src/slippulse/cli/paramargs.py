"""Parameters as command-line input, one helper for every command.

Every command takes ``--params FILE.toml`` (a ``[params]`` table, the schema of dynamic configs:
``mu, sigma, c_s, D, b, v_star, f0, phi_star, alpha``, SI; other tables are ignored so a dynamic
config serves too) and ``--set params.NAME=VALUE`` (repeatable; after the file). Three uses:

- a command that writes new pulses (``steady solve``, ``steady family``) solves with Table I, then
  the file, then the sets (:func:`params_for_output`); when its output exists with other
  parameters (a family resumed or a pulse added) it is refused, naming the parameter;
- a command that reads pulses (``analyse``, ``stability``, ``figures``, ``dynamic seed``,
  ``verify``, ``scan``) takes the parameters stored in the file (:func:`params_for_input`); any
  given value that differs from the stored one is refused, naming the parameter;
- ``dynamic run`` takes the file's ``[params]`` into its config before its own ``--set`` items
  (:func:`config_sets`).

Bad values (unknown names, non-numbers, ≤ 0, NaN, inf, out of range, a τ_ss without N shape) raise
:class:`slippulse.core.params.ParameterError`: one line, exit code 2, before any file is written.
"""
from __future__ import annotations

import os

from ..core.params import (NAMES, ParameterError, Parameters, describe_difference, differing,
                           explicit_params, read_params_file, resolve_params)

_SET_HELP = ("set one parameter (repeatable; after --params), e.g. --set params.sigma=5e6; names: "
             + ", ".join(NAMES))


def add_params_args(parser, with_set: bool = True) -> None:
    """Add ``--params FILE.toml`` and (unless the command has its own ``--set``, as ``dynamic
    run`` has) ``--set params.NAME=VALUE`` to ``parser``."""
    parser.add_argument("--params", metavar="FILE.toml", default=None,
                        help="parameters: the [params] table of a TOML file (the dynamic-config "
                             "schema; default: Table I of the paper)")
    if with_set:
        parser.add_argument("--set", dest="param_sets", action="append", default=[],
                            metavar="params.NAME=VALUE", help=_SET_HELP)


def _given(args) -> dict:
    return explicit_params(getattr(args, "params", None), getattr(args, "param_sets", ()) or ())


def stored_params(path: str) -> Parameters | None:
    """The parameters stored in an existing HDF5 output (None if the file does not exist or holds
    no ``parameters`` group)."""
    from ..core.h5io import open_h5, read_parameters

    if not os.path.isfile(path):
        return None
    with open_h5(path, "out") as h5:
        if "parameters" not in h5:
            return None
        return read_parameters(h5, path)


def params_for_output(args, out: str | None = None) -> Parameters:
    """Resolved parameters of a command that solves (Table I → ``--params`` → ``--set``),
    validated; refused if ``out`` exists with other stored parameters."""
    params = resolve_params(getattr(args, "params", None), getattr(args, "param_sets", ()) or ())
    check_solvable(params, _given(args))
    if out is not None:
        old = stored_params(out)
        if old is not None and differing(old, params):
            raise ParameterError(
                f"out={out!r} holds pulses of other parameters: "
                f"{describe_difference(old, params, 'in the file', 'given')}; "
                "use another --out or the file's parameters")
    return params


def check_solvable(params: Parameters, given: dict | None = None) -> Parameters:
    """Refuse, before any work, parameters within their ranges whose scales the steady solver
    cannot represent in floating point: the built-in starting pulse (at τ_d = 1.2 τ_min) must be
    finite and have a leading edge, where the solver pins its phase. ParameterError names the
    parameters given and the reason (e.g. sigma = 1e308 overflows the guess's slip rate)."""
    import numpy as np

    from ..steady.solver import default_guess, front_pin
    named = ", ".join(f"{k}={v:g}" for k, v in (given or {}).items()) or "these parameters"
    try:
        with np.errstate(all="ignore"):
            xi, y, _ = default_guess(params, 1.2, 64)
            if not (np.all(np.isfinite(xi)) and np.all(np.isfinite(y))):
                raise RuntimeError("the starting pulse overflows (its slip rate or grid is not "
                                   "finite)")
            front_pin(xi, y, float(np.log(params.v_stick(1.2 * params.tau_min))))
    except (RuntimeError, ValueError, ArithmeticError) as exc:
        raise ParameterError(f"parameters {named}: outside what the steady solver can handle: "
                             f"{exc}") from None
    return params


def params_for_input(args, stored: Parameters, path: str) -> Parameters:
    """The parameters of a command that reads ``path``: the stored ones. Values given with
    ``--params``/``--set`` must agree with them; the first that differs is named."""
    given = _given(args)
    if differing(given, stored):
        raise ParameterError(
            f"{path} was computed with other parameters: "
            f"{describe_difference(stored, given, 'in the file', 'given')}; a command that reads "
            "a file takes its parameters from it (omit --params/--set, or solve anew with them)")
    return stored


def check_files(args, paths) -> None:
    """:func:`params_for_input` for each HDF5 file of ``paths`` (e.g. the steady files of a scan),
    only when parameters were given."""
    from ..core.h5io import SchemaError, open_h5, read_parameters

    if not _given(args):
        return
    for path in dict.fromkeys(paths):
        with open_h5(path, "FILE") as h5:
            try:
                stored = read_parameters(h5, path)
            except SchemaError as exc:
                raise SchemaError(f"{path}: {exc}") from None
        params_for_input(args, stored, path)


def config_sets(args, sets) -> list[str]:
    """``dynamic run``: the ``[params]`` of ``--params`` as ``params.NAME=VALUE`` items placed
    before the command's own ``--set`` items (config file → --params → --set)."""
    path = getattr(args, "params", None)
    table = read_params_file(path) if path else {}
    return [f"params.{k}={v!r}" for k, v in table.items()] + list(sets)


def check_config_params(cfg: dict) -> Parameters:
    """Validate a dynamic config's resolved ``[params]`` like any other input (range, N shape)."""
    table = cfg.get("params", {})
    return resolve_params(sets=[f"params.{k}={v!r}" for k, v in table.items()])
