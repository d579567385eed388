"""Run a ``slippulse`` command in this process, as ``python -m slippulse`` would run it.

``python -m slippulse`` is ``sys.exit(main())`` (``src/slippulse/__main__.py``); a fresh process
spends 2–4 s importing numpy, scipy and numba before it parses a single argument, which the
bad-input tests paid once per case. Here ``main`` is called with stdout and stderr captured and
``SystemExit`` (argparse's usage errors and ``--help``) turned into the exit code, so a test reads
the same (returncode, stdout, stderr) as from ``subprocess.run``. An exception ``main`` does not
turn into a one-line error propagates: the test fails on it, as it would on a traceback in
stderr. The tests of the process itself (the console script, ``python -m``, kill -9) keep their
subprocesses.
"""
from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass


@dataclass
class Completed:
    returncode: int
    stdout: str
    stderr: str


def run(args) -> Completed:
    """``main([str(a) for a in args])`` with stdout and stderr captured."""
    from slippulse.cli.app import main
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in args])
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
            if not isinstance(exc.code, (int, type(None))):
                print(exc.code, file=err)
    return Completed(int(code), out.getvalue(), err.getvalue())
