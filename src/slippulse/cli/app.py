"""Command-line interface: ``slippulse steady ...``, ``slippulse figures ...``, ``slippulse dynamic ...``.

Bad input is reported as one line ``slippulse: error: ...`` naming the parameter and its valid range,
with exit code 2. A solver that does not converge exits with code 1.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from ..core.errors import UsageError
from ..core.h5io import SchemaError
from ..core.params import ParameterError

#: Modules that add sub-commands: each defines ``register(subparsers)``.
_PLUGINS = ("slippulse.cli.steady", "slippulse.cli.figures", "slippulse.cli.dynamic")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="slippulse",
        description="Self-healing slip pulses on a rate-and-state frictional interface (mode III).")
    from .. import __version__
    parser.add_argument("--version", action="version", version=f"slippulse {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in _PLUGINS:
        try:
            mod = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:
                raise
            continue
        mod.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (ParameterError, SchemaError, UsageError) as exc:
        print(f"slippulse: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:          # a path that cannot be read or written (named by the OS error)
        where = f": {exc.filename!r}" if exc.filename else ""
        print(f"slippulse: error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("slippulse: interrupted", file=sys.stderr)
        return 130
