"""Scans: many independent simulations described by one TOML file, run through an executor.

A scan is a list of *cases* (flat dicts of scalars). Each case is handed to a *runner* function,
``run_case(case, out_path) -> row``, in a worker process; the runner writes one HDF5 file per case
and returns a flat dict of scalars (the case's summary row). The scan collects the rows into
``out_dir/summary.csv`` and ``out_dir/summary.h5`` and, if the runner's module defines
``scan_figures(rows, out_dir)``, lets it draw the scan's figures.

SCAN.toml
---------
::

    [scan]
    name = "growth_td1.05"                   # required
    out_dir = "runs/scans/growth_td1.05"     # required; relative to the current directory
    runner = "slippulse.timedomain.perturbation:run_case"  # optional ("module:function", this default)
    runner_path = ["tools"]                  # optional: directories prepended to sys.path (in the
                                             # main process and in every worker) to import runner
    [defaults]                               # keys shared by every case (any scalar)
    steady = "runs/family_n3000.h5"
    dx = 4e-3
    [grid]                                   # optional: lists, cartesian product
    label = ["td1.0500"]
    eps = [1e-3, -1e-3, 1e-2, -1e-2]
    [[case]]                                 # optional: extra explicit cases (over [defaults])
    label = "td1.1000"
    eps = 1e-3

Cases are the cartesian product of the ``[grid]`` lists (in TOML order, the last key varying
fastest), each merged over ``[defaults]``, followed by the ``[[case]]`` tables, each merged over
``[defaults]``. Values are str, int, float (finite) or bool; the keys ``id`` and ``status`` are
reserved. Unknown top-level tables or ``[scan]`` keys, non-scalar values, an empty scan and duplicate
cases are errors (:class:`slippulse.core.errors.UsageError`, naming the key and what is allowed).

Case ids and files
------------------
Each case gets a readable, deterministic id: the ``key=value`` pairs of the keys the case sets
itself (its ``[grid]`` keys, or the keys of its ``[[case]]`` table), sanitised for file names, plus
the first 8 hex digits of the SHA-1 of ``json.dumps(case, sort_keys=True)``, e.g.
``label=td1.0500_eps=-0.001_3fa2b1c0``. The id depends on that case alone, so adding cases to a
scan never renames the files of the others; changing a default changes every hash (those cases are
new). The output of a case is ``out_dir/<id>.h5``.

Runner contract
---------------
``runner = "module:function"`` names ``run_case(case: dict, out_path: str) -> dict``. It writes
``out_path`` atomically and, on success, sets the root attributes ``complete = True`` and
``case_json = json.dumps(case, sort_keys=True)``; it returns the summary row (flat dict of scalars).
The same module must define ``read_row(out_path) -> dict`` (the row read back from a finished file,
used on resume) and may define ``scan_figures(rows, out_dir) -> list[str]``.

Workers import the runner by its module name: it must be importable there (installed, on
``PYTHONPATH``, or in a ``runner_path`` directory; on a remote Dask cluster the directory must exist
on the workers' machines, as an absolute path).

Execution and resume
--------------------
Before anything is submitted, each case's file is checked: a file with ``complete == True`` and the
same case (stored ``case_json``) is *reused* (its row comes from ``read_row``); a file holding another
case is an error naming the file unless ``overwrite``; a missing, incomplete or unreadable file is
(re)run. The remaining cases run through

* ``executor="local"``: a :class:`concurrent.futures.ProcessPoolExecutor` of ``workers`` processes
  (default 1: the runs are CPU-bound and may use several threads each, so keep
  ``workers × threads per run`` within the cores). Workers are started with the ``spawn`` method:
  a fresh interpreter per worker, which is safe with numba and pyfftw (forking a process that
  already runs threads is not) and behaves the same on Linux, macOS and Windows.
* a :class:`distributed.Client` (or a scheduler address, which is connected to): one task per case
  (``pure=False``), gathered with :func:`distributed.as_completed`. Dask is imported only here.

A case whose runner raises gets the row ``status = "error: <Type>: <message>"``; the other cases go
on and :attr:`ScanResult.n_errors` counts it (the CLI exits with 1). Its file is never marked
complete by the scan, so a later run retries it. On Ctrl-C pending cases are cancelled; finished
files stay and the next run resumes from them.

Summary
-------
One row per case, in case order: ``id``, ``status`` (``"ok"``, the runner's own ``status`` if its
row has one, or ``"error: ..."``), the case keys, then the runner's row keys (a row key equal to a
case key is dropped when the values agree, else stored as ``<key>_result``). ``summary.csv`` has the
union of the columns (empty cells where a row lacks one); ``summary.h5`` has one dataset per column
(bool, int64, float64 with NaN for missing values, or variable-length str), the attribute
``columns`` (their order) and the attributes ``scan_name``, ``scan_toml``, ``runner``, written
atomically (:func:`slippulse.core.h5io.atomic_update`).
"""
from __future__ import annotations

import csv
import hashlib
import importlib
import itertools
import json
import math
import os
import re
import sys
import time
import tomllib
from dataclasses import dataclass, field

from ..core.atomic import replacing_open
from ..core.errors import UsageError

DEFAULT_RUNNER = "slippulse.timedomain.perturbation:run_case"
TOP_LEVEL = ("scan", "defaults", "grid", "case")
SCAN_KEYS = {"name": "str, required", "out_dir": "str, required",
             "runner": f"'module:function', default {DEFAULT_RUNNER!r}",
             "runner_path": "list of directories"}
RESERVED = ("id", "status")
_ID_MAX = 96          # characters of the readable part of an id


# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class Case:
    """One case of a scan: its id and its flat parameters (scalars)."""

    id: str
    params: dict

    @property
    def case_json(self) -> str:
        return case_json(self.params)


@dataclass
class Scan:
    """A parsed scan: name, absolute output directory, runner and its cases."""

    name: str
    out_dir: str
    cases: list[Case]
    runner: str = DEFAULT_RUNNER
    runner_path: tuple[str, ...] = ()
    toml_text: str = ""
    source: str = ""

    def out_file(self, case: Case) -> str:
        """Output HDF5 file of ``case``: ``out_dir/<id>.h5``."""
        return os.path.join(self.out_dir, case.id + ".h5")


@dataclass
class ScanResult:
    """Outcome of :func:`run_scan`: rows in case order, counts, wall time and written files."""

    scan: Scan
    rows: list[dict]
    n_run: int
    n_reused: int
    n_errors: int
    wall: float
    summary_csv: str
    summary_h5: str
    figures: list[str] = field(default_factory=list)
    figure_error: str | None = None

    @property
    def ok(self) -> bool:
        return self.n_errors == 0 and self.figure_error is None

    def line(self) -> str:
        """The one-line summary printed by the CLI."""
        return (f"scan {self.scan.name}: {len(self.rows)} cases, {self.n_run} run, "
                f"{self.n_reused} reused, {self.n_errors} errors, wall {self.wall:.1f} s; "
                f"summary: {self.summary_csv}")


# --------------------------------------------------------------------------- parsing


def case_json(params: dict) -> str:
    """Canonical JSON of a case (what the runner stores as the ``case_json`` attribute)."""
    return json.dumps(params, sort_keys=True)


def _check_scalar(where: str, value):
    if isinstance(value, float) and not math.isfinite(value):
        raise UsageError(f"scan key {where}={value!r} must be finite")
    if not isinstance(value, (str, int, float, bool)):
        raise UsageError(f"scan key {where}={value!r} must be a scalar (str, int, float or bool), "
                         f"not {type(value).__name__}")
    return value


def _check_table(where: str, table) -> dict:
    if not isinstance(table, dict):
        raise UsageError(f"scan: [{where}] must be a table of key = value")
    for key, value in table.items():
        if key in RESERVED:
            raise UsageError(f"scan key {where}.{key} is reserved (reserved: {', '.join(RESERVED)})")
        if where != "grid":
            _check_scalar(f"{where}.{key}", value)
    return table


def _sanitise(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._=+-]+", "-", text)


def _fmt(value) -> str:
    return value if isinstance(value, str) else repr(value)


def case_id(params: dict, keys) -> str:
    """Id of a case: ``key=value`` of ``keys`` (sanitised) + ``_`` + 8 hex of the case's SHA-1."""
    digest = hashlib.sha1(case_json(params).encode()).hexdigest()[:8]
    readable = _sanitise("_".join(f"{k}={_fmt(params[k])}" for k in keys if k in params))
    readable = readable.strip("-.")[:_ID_MAX]
    return f"{readable}_{digest}" if readable else f"case_{digest}"


def expand_cases(defaults: dict | None = None, grid: dict | None = None,
                 explicit: list | tuple = ()) -> list[Case]:
    """Cases of a scan: the cartesian product of ``grid`` then the ``explicit`` cases.

    Parameters
    ----------
    defaults : dict, optional
        Keys shared by every case (scalars).
    grid : dict, optional
        ``key -> non-empty list of scalars``; the product is taken in dict order, the last key
        varying fastest. Each combination is merged over ``defaults``.
    explicit : sequence of dict
        Extra cases, each merged over ``defaults``.

    Returns
    -------
    list of Case
        With unique ids (see :func:`case_id`).

    Raises
    ------
    UsageError
        Non-scalar values, empty or non-list grid entries, reserved keys, duplicate cases, or no
        case at all.
    """
    defaults = _check_table("defaults", dict(defaults or {}))
    grid = _check_table("grid", dict(grid or {}))
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise UsageError(f"scan key grid.{key}={values!r} must be a non-empty list of scalars")
        for i, v in enumerate(values):
            _check_scalar(f"grid.{key}[{i}]", v)
    cases: list[Case] = []
    if grid:
        keys = list(grid)
        for combo in itertools.product(*(grid[k] for k in keys)):
            params = {**defaults, **dict(zip(keys, combo))}
            cases.append(Case(case_id(params, keys), params))
    if not isinstance(explicit, (list, tuple)):
        raise UsageError("scan: 'case' must be an array of tables: write each case as [[case]]")
    for i, table in enumerate(explicit):
        _check_table(f"case[{i}]", table)
        params = {**defaults, **table}
        cases.append(Case(case_id(params, list(table)), params))
    if not cases:
        raise UsageError("scan defines no cases: give [grid] lists and/or [[case]] tables")
    seen: dict[str, int] = {}
    for i, c in enumerate(cases):
        if c.id in seen:
            raise UsageError(f"scan: cases {seen[c.id]} and {i} are identical (id {c.id}); "
                             "each case must differ")
        seen[c.id] = i
    return cases


def _split_runner(spec) -> tuple[str, str]:
    if not isinstance(spec, str) or not re.fullmatch(r"[A-Za-z_][\w.]*:[A-Za-z_]\w*", spec):
        raise UsageError(f"scan key scan.runner={spec!r} must be 'module:function', e.g. "
                         f"{DEFAULT_RUNNER!r}")
    mod, func = spec.split(":")
    return mod, func


def parse_scan(data: dict, text: str = "", origin: str = "<scan>") -> Scan:
    """Build a :class:`Scan` from parsed TOML ``data`` (see the module docstring for the format).

    Relative ``out_dir`` and ``runner_path`` entries are made absolute against the current
    directory.
    """
    unknown = [k for k in data if k not in TOP_LEVEL]
    if unknown:
        raise UsageError(f"{origin}: unknown top-level table or key {unknown[0]!r}; known: "
                         f"{', '.join('[' + t + ']' for t in TOP_LEVEL[:3])}, [[case]]")
    head = data.get("scan")
    if not isinstance(head, dict):
        raise UsageError(f"{origin}: missing [scan] table (keys: name, out_dir, runner)")
    for key in head:
        if key not in SCAN_KEYS:
            raise UsageError(f"{origin}: unknown key scan.{key}; known: "
                             + ", ".join(f"{k} ({v})" for k, v in SCAN_KEYS.items()))
    for key in ("name", "out_dir"):
        if key not in head:
            raise UsageError(f"{origin}: missing required key scan.{key} (a non-empty string)")
        if not isinstance(head[key], str) or not head[key].strip():
            raise UsageError(f"{origin}: scan.{key}={head[key]!r} must be a non-empty string")
    runner = head.get("runner", DEFAULT_RUNNER)
    try:
        _split_runner(runner)
    except UsageError as exc:
        raise UsageError(f"{origin}: {exc}") from None
    rpath = head.get("runner_path", [])
    if isinstance(rpath, str):
        rpath = [rpath]
    if not isinstance(rpath, list) or not all(isinstance(p, str) and p for p in rpath):
        raise UsageError(f"{origin}: scan.runner_path={rpath!r} must be a list of directories")
    try:
        cases = expand_cases(data.get("defaults"), data.get("grid"), data.get("case", []))
    except UsageError as exc:
        raise UsageError(f"{origin}: {exc}") from None
    return Scan(name=head["name"], out_dir=os.path.abspath(head["out_dir"]), cases=cases,
                runner=runner, runner_path=tuple(os.path.abspath(p) for p in rpath),
                toml_text=text, source=origin)


def load_scan(path: str) -> Scan:
    """Read and parse a SCAN.toml file (:func:`parse_scan`); errors name the file."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except FileNotFoundError:
        raise UsageError(f"scan file {path} not found") from None
    except OSError as exc:
        raise UsageError(f"scan file {path}: {exc.strerror}") from None
    text = raw.decode("utf-8", errors="replace")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UsageError(f"{path}: invalid TOML: {exc}") from None
    return parse_scan(data, text=text, origin=path)


# --------------------------------------------------------------------------- runner


def _extend_path(dirs) -> None:
    for d in reversed(tuple(dirs)):
        if d not in sys.path:
            sys.path.insert(0, d)


def load_runner(spec: str, runner_path=()) -> tuple:
    """Import ``module:function``; return ``(run_case, module)``. Errors name ``scan.runner``."""
    mod_name, func = _split_runner(spec)
    _extend_path(runner_path)
    try:
        mod = importlib.import_module(mod_name)
    except ImportError as exc:
        raise UsageError(f"scan.runner={spec!r}: cannot import {mod_name} ({exc}); add its "
                         "directory to scan.runner_path or PYTHONPATH") from None
    fn = getattr(mod, func, None)
    if not callable(fn):
        raise UsageError(f"scan.runner={spec!r}: {mod_name} has no function {func!r}")
    return fn, mod


def _clean_row(row) -> dict:
    """The runner's row as a dict of Python scalars (numpy scalars converted, None dropped)."""
    if not isinstance(row, dict):
        raise TypeError(f"runner returned {type(row).__name__}, expected a dict of scalars")
    out = {}
    for k, v in row.items():
        if hasattr(v, "item") and getattr(v, "shape", None) == ():
            v = v.item()
        if v is None:
            continue
        if isinstance(v, bytes):
            v = v.decode()
        if not isinstance(v, (str, int, float, bool)):
            raise TypeError(f"runner row value {k}={v!r} is not a scalar")
        out[str(k)] = v
    return out


def _one_line(exc: BaseException) -> str:
    msg = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {msg}" if msg else type(exc).__name__


def run_one(runner: str, params: dict, out_path: str, runner_path=()) -> tuple[str, object]:
    """Worker task: run one case. Returns ``("ok", row)`` or ``("error", message)``, never raises
    for a failing runner (its exception class might not unpickle in the main process)."""
    try:
        fn, _ = load_runner(runner, runner_path)
        return "ok", _clean_row(fn(dict(params), out_path))
    except Exception as exc:                                   # noqa: BLE001 - reported per case
        return "error", _one_line(exc)


# --------------------------------------------------------------------------- resume


def case_state(path: str, case: Case) -> str:
    """State of a case's output file: ``"missing"``, ``"done"``, ``"incomplete"`` (unfinished or
    unreadable: rerun) or ``"other"`` (holds another case)."""
    if not os.path.exists(path):
        return "missing"
    from ..core.h5io import open_h5

    try:
        with open_h5(path) as h5:
            complete = h5.attrs.get("complete", False)
            stored = h5.attrs.get("case_json", None)
    except Exception:                                          # noqa: BLE001 - corrupt: rerun
        return "incomplete"
    if isinstance(stored, bytes):
        stored = stored.decode()
    if stored is not None:
        try:
            same = json.loads(str(stored)) == json.loads(case.case_json)
        except ValueError:
            same = False
        if not same:
            return "other"
    return "done" if bool(complete) and stored is not None else "incomplete"


def scan_states(scan: Scan) -> list[str]:
    """:func:`case_state` of every case of ``scan``, in case order."""
    return [case_state(scan.out_file(c), c) for c in scan.cases]


# --------------------------------------------------------------------------- executor


def _run_cases(todo, scan: Scan, pool):
    """Yield ``(index, outcome)`` as cases finish on `pool` (one task per case)."""
    handles = {pool.submit(run_one, scan.runner, c.params, scan.out_file(c), scan.runner_path): i
               for i, c in todo}
    for h, outcome, err in pool.completed():
        if err is not None:                          # e.g. KilledWorker: the case, not the scan
            outcome = ("error", _one_line(err))
        yield handles.pop(h), outcome


# --------------------------------------------------------------------------- summary


def summary_row(case: Case, status: str, row: dict | None) -> dict:
    """Summary row: id, status, the case keys, then the runner's row keys (see module docstring)."""
    out = {"id": case.id, "status": status}
    out.update(case.params)
    for k, v in (row or {}).items():
        if k == "status":
            if status == "ok":
                out["status"] = v
            continue
        if k in out:
            if out[k] == v:
                continue
            k = f"{k}_result"
        out[k] = v
    return out


def _columns(rows: list[dict]) -> list[str]:
    cols: dict[str, None] = {}
    for r in rows:
        cols.update(dict.fromkeys(r))
    return list(cols)


def write_csv(path: str, rows: list[dict]) -> None:
    """``rows`` as CSV (union of the columns, empty cells for missing values), atomically."""
    cols = _columns(rows)
    with replacing_open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=cols, restval="")
        w.writeheader()
        for r in rows:
            w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()})


def _column_array(values: list):
    import h5py
    import numpy as np

    present = [v for v in values if v is not None]
    if present and len(present) == len(values) and all(isinstance(v, bool) for v in values):
        return np.array(values, dtype=bool)
    if present and len(present) == len(values) and all(
            isinstance(v, int) and not isinstance(v, bool) for v in values):
        return np.array(values, dtype=np.int64)
    if present and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in present):
        return np.array([math.nan if v is None else float(v) for v in values], dtype=float)
    return np.array(["" if v is None else str(v) for v in values],
                    dtype=h5py.string_dtype(encoding="utf-8"))


#: Units of the summary columns of the stability runner (others: "1").
SUMMARY_UNITS = {"s_per_s": "1/s", "s_per_s_err": "1/s", "t_end": "s", "L_end": "m",
                 "v_max_end": "m/s", "wall_time": "s", "L0": "m", "c_p0": "m/s",
                 "v_max0": "m/s", "dx": "m", "run_wall_time": "s", "s_per_L": "1/L0",
                 "s_per_L_err": "1/L0", "s_per_L_from_L": "1/L0"}


def write_summary_h5(path: str, rows: list[dict], scan: Scan) -> None:
    """``rows`` as one dataset per column in ``path`` (atomic; replaces earlier contents).

    Format version 2 (``xarray.open_dataset(path, engine="h5netcdf")``): every column lies on
    the dimension ``id`` whose coordinate is the case id (a dimension scale), with ``units``
    (:data:`SUMMARY_UNITS`, else "1") and ``long_name`` (the column name).
    """
    import h5py

    from ..core.h5io import atomic_update, describe, dimension, stamp_format

    cols = _columns(rows)

    def fill(h5):
        for k in list(h5):
            del h5[k]
        stamp_format(h5, "scan-summary")
        # dimension "id" (one entry per case; its coordinate is the case id column)
        dim = None
        if "id" in cols:
            ids = [str(r.get("id")) for r in rows]
            dim = h5.create_dataset("id", data=ids, dtype=h5py.string_dtype(encoding="utf-8"))
            dim.make_scale("id")
            describe(dim, "1", "case id")
        elif rows:
            dim = dimension(h5, "case", len(rows))
        for col in cols:
            if col == "id":
                continue
            ds = h5.create_dataset(col.replace("/", "_"),
                                   data=_column_array([r.get(col) for r in rows]))
            describe(ds, SUMMARY_UNITS.get(col, "1"), col, dims=(dim,) if dim is not None else ())
        h5.attrs["columns"] = cols
        h5.attrs["scan_name"] = scan.name
        h5.attrs["scan_toml"] = scan.toml_text
        h5.attrs["runner"] = scan.runner
        h5.attrs["n_cases"] = len(rows)

    atomic_update(path, fill, replace=True)


def read_summary_h5(path: str) -> list[dict]:
    """Rows of a ``summary.h5`` (the inverse of :func:`write_summary_h5`; NaN/"" kept as such)."""
    from ..core.h5io import open_h5

    with open_h5(path) as h5:
        cols = [c.decode() if isinstance(c, bytes) else str(c) for c in h5.attrs["columns"]]
        data = {}
        for c in cols:
            ds = h5[c.replace("/", "_")]
            data[c] = list(ds.asstr()[()]) if ds.dtype.kind == "O" else ds[()].tolist()
    n = len(data[cols[0]]) if cols else 0
    return [{c: data[c][i] for c in cols} for i in range(n)]


# --------------------------------------------------------------------------- driver


def run_scan(scan: Scan, executor=None, overwrite: bool = False, progress: bool = True,
             figures=None) -> ScanResult:
    """Run the cases of ``scan`` that are not finished yet, then write the summary and figures.

    Parameters
    ----------
    scan : Scan
        From :func:`load_scan` or :func:`parse_scan`.
    executor : ExecutorSettings, distributed.Client or None
        Where the cases run (:class:`slippulse.core.executor.ExecutorSettings`: this process, a
        local Dask cluster or a scheduler's; None: this process). A :class:`distributed.Client`:
        its cluster (the client is left open).
    overwrite : bool
        Rerun cases whose output file holds another case (default: error naming the file).
    progress : bool
        Show a tqdm bar over the cases.
    figures : callable ``(rows, out_dir) -> list[str]`` or None
        Draws the scan's figures after the summary; None: the runner module's ``scan_figures``
        if it has one (the perturbation runner's is ``slippulse.plotting.stability.scan_figures``,
        passed by ``slippulse dynamic scan``).

    Returns
    -------
    ScanResult
        Rows in case order; ``n_errors`` counts failed cases (their rows say ``"error: ..."``).

    Raises
    ------
    UsageError
        Bad runner, a file that holds another case (without ``overwrite``).
    """
    from ..core.executor import ExecutorSettings, TaskPool, progress_bar

    client = None if executor is None or isinstance(executor, ExecutorSettings) else executor
    settings = executor if isinstance(executor, ExecutorSettings) else ExecutorSettings()
    t0 = time.perf_counter()
    _, module = load_runner(scan.runner, scan.runner_path)
    read_row = getattr(module, "read_row", None)
    if not callable(read_row):
        raise UsageError(f"scan.runner={scan.runner!r}: module {module.__name__} has no read_row"
                         "(out_path) function (needed to reuse finished runs)")
    states = scan_states(scan)
    if not overwrite:
        clash = [scan.out_file(c) for c, s in zip(scan.cases, states) if s == "other"]
        if clash:
            raise UsageError(f"output file {clash[0]} holds another case (stored case_json "
                             f"differs{'' if len(clash) == 1 else f'; {len(clash)} files'}): use "
                             "--overwrite to rerun it, or another scan.out_dir")
    os.makedirs(scan.out_dir, exist_ok=True)
    rows: list[dict | None] = [None] * len(scan.cases)
    n_errors = n_reused = 0
    for i, (c, s) in enumerate(zip(scan.cases, states)):
        if s == "done":
            try:
                rows[i] = summary_row(c, "ok", _clean_row(read_row(scan.out_file(c))))
            except Exception as exc:                           # noqa: BLE001 - reported per case
                rows[i] = summary_row(c, f"error: read_row: {_one_line(exc)}", None)
                n_errors += 1
            n_reused += 1
    todo = [(i, c) for i, (c, s) in enumerate(zip(scan.cases, states)) if s != "done"]

    bar = progress_bar(len(scan.cases), f"scan {scan.name}", "case", initial=n_reused,
                       disable=not progress)
    try:
        if todo:
            with TaskPool(settings, client=client) as pool:
                for i, (kind, value) in _run_cases(todo, scan, pool):
                    case = scan.cases[i]
                    if kind == "ok":
                        rows[i] = summary_row(case, "ok", value)
                    else:
                        rows[i] = summary_row(case, f"error: {value}", None)
                        n_errors += 1
                    bar.update(1)
                    if n_errors:
                        bar.set_postfix_str(f"{n_errors} errors", refresh=False)
    finally:
        bar.close()

    final = [r for r in rows if r is not None]
    csv_path = os.path.join(scan.out_dir, "summary.csv")
    h5_path = os.path.join(scan.out_dir, "summary.h5")
    write_csv(csv_path, final)
    write_summary_h5(h5_path, final, scan)
    draw = figures if figures is not None else getattr(module, "scan_figures", None)
    figures, fig_error = [], None
    if callable(draw):
        try:
            figures = list(draw(final, scan.out_dir) or [])
        except Exception as exc:                               # noqa: BLE001 - results are saved
            fig_error = _one_line(exc)
    return ScanResult(scan=scan, rows=final, n_run=len(todo), n_reused=n_reused,
                      n_errors=n_errors, wall=time.perf_counter() - t0, summary_csv=csv_path,
                      summary_h5=h5_path, figures=figures, figure_error=fig_error)


def pack_scan(scan_dir: str, dest: str) -> tuple[int, int]:
    """The scan directory small enough to carry off a lent machine: a gzipped tar at ``dest``
    whose case files keep their attributes and every group but the slip-rate snapshots (of
    ``snapshots`` only its times and front positions), the summaries and tables as they are,
    no figures (they are redrawn from the cases). Written to a temporary name, then renamed.
    Returns (files packed, bytes). A missing directory raises UsageError."""
    import glob
    import tarfile
    import tempfile

    import h5py
    if not os.path.isdir(scan_dir):
        raise UsageError(f"SCAN_DIR={scan_dir!r}: no such directory")
    root = os.path.basename(os.path.normpath(scan_dir))
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(os.path.abspath(dest)), suffix=".part")
    os.close(fd)
    n = 0
    try:
        with tarfile.open(tmp, "w:gz") as tar, tempfile.TemporaryDirectory() as work:
            for f in sorted(glob.glob(os.path.join(scan_dir, "*"))):
                name = os.path.basename(f)
                if name.endswith(".png") or not os.path.isfile(f):
                    continue
                src = f
                if name.endswith(".h5") and not name.startswith("summary"):
                    src = os.path.join(work, name)
                    with h5py.File(f, "r") as h, h5py.File(src, "w") as s:
                        s.attrs.update(dict(h.attrs))
                        for k in h:
                            if k != "snapshots":
                                h.copy(k, s)
                        if "snapshots" in h:
                            g = s.create_group("snapshots")
                            g.attrs.update(dict(h["snapshots"].attrs))
                            for k in ("t", "x_front"):
                                if k in h["snapshots"]:
                                    h.copy(f"snapshots/{k}", g)
                tar.add(src, arcname=os.path.join(root, name))
                n += 1
        os.replace(tmp, dest)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return n, os.path.getsize(dest)
