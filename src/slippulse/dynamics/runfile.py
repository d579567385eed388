"""HDF5 output of dynamic runs: snapshots, per-step scalars, checkpoints, bit-exact resume.

Layout (format version 2, netCDF-4 conventions: ``xarray.open_datatree(FILE, engine="h5netcdf")``
reads it with named dimensions and coordinates)::

    /                 attrs: slippulse_version, created, kind="dynamic", format="slippulse-dynamic",
                      format_version=2, status, message
    /x                (x,) m: grid coordinate (dimension scale)
    /parameters       attrs: the Table-I parameters (SI) + units_<name>
    /config           attrs: toml-like "section.key" = value (the resolved config), json (all of it)
    /snapshots/t      (t,) s, resizable time axis (dimension scale); step (t,);
                      V, phi, tau, delta: (t, x), one resizable dataset per field
    /scalars/t        (t,) s, one entry per step (dimension scale); step, dt (s), v_max (m/s),
                      x_vmax (m), iters (1): (t,)
    /checkpoint       the full solver state at the last checkpoint (0-d datasets for t, nstep,
                      dt_prev; arrays on x or on dimensions ``dim_<name>_<axis>``)

Every dataset has ``units`` and ``long_name``. Version 1 files (no ``format_version``; the grid in
``/grid/x`` and no dimension scales) are still read and resumed: ``--resume`` upgrades the copy it
continues. Files of a newer version are refused with a message naming it.

Crash safety (a kill at any moment leaves FILE complete as of the last checkpoint): the run writes
into ``FILE.partial``, which it owns for its whole life (an exclusive lock: a second run or resume
of FILE is refused), through :class:`~slippulse.core.guarded.GuardedFile` (a full disk stops the
run at the next snapshot or checkpoint with one error naming the file, FILE left at its last
checkpoint, the work file removed; HDF5 never sees the failed write). Publishing holds FILE's lock. At a checkpoint that file is closed and renamed over ``FILE`` (``os.replace``
is atomic); the previous ``FILE`` (kept by a hard link) becomes the next ``FILE.partial`` and is
brought up to date by appending what it lacks — the snapshot and scalar rows of the last interval,
read back from ``FILE``, and the checkpoint state. A checkpoint therefore costs the data of one
interval, not a copy of the whole file (benchmarks/bench_checkpoint.py, BENCHMARKS.md). Where hard
links are not available the previous FILE is copied instead. ``--resume`` copies ``FILE`` to
``FILE.partial`` once and continues from its checkpoint; the results are bit-identical to an
uninterrupted run because the checkpoint holds every array the next step reads.
"""
from __future__ import annotations

import datetime as _dt
import json
import os
import shutil

import h5py
import numpy as np

from .. import __version__
from ..core.atomic import read_only
from ..core.guarded import GuardedFile
from ..core.killpoint import kill_point as _kill_point
from ..core.h5io import (SchemaError, atomic_update, coordinate, describe, dimension,
                         format_version, open_h5, stamp_format)
from ..core.locking import file_lock, hold_exclusive
from ..core.params import Parameters

SNAP_FIELDS = {"V": "m/s", "phi": "s", "tau": "Pa", "delta": "m"}
SCALARS = {"t": "s", "dt": "s", "v_max": "m/s", "x_vmax": "m", "iters": "1"}
LONG_NAMES = {"x": "position along the interface", "t": "time",
              "step": "time step number", "V": "slip rate", "phi": "state variable",
              "tau": "shear stress", "delta": "slip", "dt": "time step",
              "v_max": "maximum slip rate", "x_vmax": "position of the maximum slip rate",
              "iters": "friction-solver iterations (max of the step's two solves)"}
#: Units of the checkpoint arrays (the rest are 1).
_STATE_UNITS = {"t": "s", "dt_prev": "s", "delta": "m", "V": "m/s", "phi": "s", "tau": "Pa",
                "delta_k": "m", "V_k": "m/s"}


#: Points of :meth:`RunFile.checkpoint` (and of the catch-up it calls) where the test hook
#: ``SLIPPULSE_KILL_AT=POINT:N`` (:mod:`slippulse.core.killpoint`) kills the process the N-th
#: time it gets there (tests/test_kill_safety.py: kills at defined moments, not random delays).
KILL_POINTS = ("state_written", "closed", "linked", "published", "rows_caught_up", "reopened")


def _create_series(h5, n: int) -> None:
    """The v2 groups snapshots (t, x) and scalars (t), empty and resizable."""
    x = h5["x"]
    gs = h5.create_group("snapshots")
    t = coordinate(gs, "t", units="s", long_name="time of the snapshot", unlimited=True,
                   chunks=(256,))
    describe(gs.create_dataset("step", shape=(0,), maxshape=(None,), dtype="i8", chunks=(256,)),
             "1", LONG_NAMES["step"], dims=(t,))
    for name, unit in SNAP_FIELDS.items():
        describe(gs.create_dataset(name, shape=(0, n), maxshape=(None, n), dtype="f8",
                                   chunks=(1, n)), unit, LONG_NAMES[name], dims=(t, x))
    gsc = h5.create_group("scalars")
    t = coordinate(gsc, "t", units="s", long_name="time at the end of the step", unlimited=True,
                   chunks=(4096,))
    describe(gsc.create_dataset("step", shape=(0,), maxshape=(None,), dtype="i8", chunks=(4096,)),
             "1", LONG_NAMES["step"], dims=(t,))
    for name, unit in SCALARS.items():
        if name != "t":
            describe(gsc.create_dataset(name, shape=(0,), maxshape=(None,),
                                        dtype="i8" if name == "iters" else "f8", chunks=(4096,)),
                     unit, LONG_NAMES[name], dims=(t,))


def upgrade_v1(h5) -> None:
    """Bring an open version-1 run file to version 2 in place (same data, dimension scales added;
    the grid moves from /grid/x to /x)."""
    if format_version(h5) >= 2:
        return
    x = coordinate(h5, "x", h5["grid/x"][...], units="m", long_name=LONG_NAMES["x"])
    del h5["grid"]
    for gname in ("snapshots", "scalars"):
        g = h5[gname]
        t = g["t"]
        t.make_scale("t")
        describe(t, "s", LONG_NAMES["t"])
        for name, ds in g.items():
            if name != "t":
                describe(ds, ds.attrs.get("units", "1"), LONG_NAMES.get(name, name),
                         dims=(t, x)[:ds.ndim])
    if "checkpoint" in h5:                      # v1 datasets carry no scales: recreate them
        policy = h5["checkpoint"].attrs.get("history_policy")
        state = read_checkpoint(h5)
        del h5["checkpoint"]
        _write_checkpoint(h5, state, policy)
    stamp_format(h5, "dynamic")


def _drop(ds) -> None:
    """Delete a dataset, detaching its dimension scales first (no dangling references)."""
    for axis in range(ds.ndim):
        for scale in list(ds.dims[axis].values()):
            ds.dims[axis].detach_scale(scale)
    del ds.parent[ds.name.rsplit("/", 1)[-1]]


def _write_checkpoint(h5, state: dict, history_policy) -> None:
    """Write the group /checkpoint from a state dict (``stepper.state()``).

    Datasets whose shape and type are unchanged are overwritten in place (a new dataset per
    checkpoint would leave the old one's space unused in the file); the others are replaced.
    """
    g = h5.require_group("checkpoint")
    x = h5["x"]
    n = x.shape[0]
    stale = []
    g.visititems(lambda name, obj: stale.append(name) if isinstance(obj, h5py.Dataset)
                 and not obj.is_scale and name not in state else None)
    for name in stale:
        _drop(g[name])
    for key, val in state.items():
        arr = np.asarray(val)
        old = g.get(key)
        if isinstance(old, h5py.Dataset) and old.shape == arr.shape and old.dtype == arr.dtype:
            old[()] = arr                        # 0-d datasets for scalars: exact
            continue
        if old is not None:
            _drop(old)
        ds = g.create_dataset(key, data=arr)
        leaf = key.rsplit("/", 1)[-1]
        dims = []
        for axis, size in enumerate(arr.shape):
            if arr.ndim == 1 and size == n:
                dims.append(x)
                continue
            name = f"dim_{leaf}_{axis}"
            dim = ds.parent.get(name)
            if dim is not None and dim.shape != (size,):
                del ds.parent[name]              # its only user was the dataset dropped above
                dim = None
            dims.append(dim if dim is not None else dimension(ds.parent, name, size))
        describe(ds, _STATE_UNITS.get(key, "1"), f"solver state: {key}", dims=dims)
    if history_policy is not None:
        g.attrs["history_policy"] = history_policy


class RunFile:
    """Writer of one dynamic run (see module docstring)."""

    def __init__(self, path: str, raw: GuardedFile, h5: h5py.File, lock):
        self.path = path
        self.work = path + ".partial"
        self.h5 = h5
        self._raw = raw
        self._lock = lock
        self._buf = {k: [] for k in ("step", *SCALARS)}

    # ------------------------------------------------------------------ creation / resume
    @staticmethod
    def _own(path: str):
        """The run's lock on its work file; a stale work file (a killed run's) is removed."""
        work = path + ".partial"
        lock = hold_exclusive(work, "another dynamic run")
        try:
            if os.path.lexists(work):
                os.remove(work)
        except OSError:
            lock.release()
            raise
        return lock

    @classmethod
    def create(cls, path: str, cfg: dict, params: Parameters, stepper) -> "RunFile":
        work = path + ".partial"
        lock = cls._own(path)
        try:
            raw = GuardedFile(work, "w+b")
            h5 = h5py.File(raw, "w")
        except BaseException:
            _remove(work)
            lock.release()
            raise
        h5.attrs["slippulse_version"] = __version__
        h5.attrs["created"] = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
        h5.attrs["kind"] = "dynamic"
        stamp_format(h5, "dynamic")
        h5.attrs["status"] = "running"
        h5.attrs["message"] = ""
        gp = h5.create_group("parameters")
        for name, val in params.as_dict().items():
            gp.attrs[name] = val
            gp.attrs[f"units_{name}"] = Parameters.UNITS[name]
        gc = h5.create_group("config")
        gc.attrs["json"] = json.dumps(cfg, sort_keys=True)
        for section, table in cfg.items():
            for key, val in table.items():
                gc.attrs[f"{section}.{key}"] = val
        coordinate(h5, "x", stepper.x, units="m", long_name=LONG_NAMES["x"])
        _create_series(h5, stepper.n)
        return cls(path, raw, h5, lock)

    @classmethod
    def open_resume(cls, path: str) -> tuple["RunFile", dict, dict]:
        """Reopen FILE for appending; returns (writer, stored config, checkpoint state).

        Raises FileNotFoundError (no FILE) or ValueError (not a run file with a checkpoint,
        unreadable, of a newer format version, read-only, or already being run), with a message
        naming FILE. Nothing is written before FILE is known to be writable and valid.
        """
        if not os.path.exists(path):
            raise FileNotFoundError(f"--resume: output file {path} does not exist")
        try:
            with open_h5(path, "--resume") as h5:
                ok = h5.attrs.get("kind") == "dynamic" and "checkpoint" in h5
                format_version(h5, path)
                if ok:
                    read_checkpoint(h5, path)
        except SchemaError as exc:
            raise ValueError(str(exc) if str(exc).startswith("--resume") else
                             f"--resume: {exc}") from None
        if not ok:
            raise ValueError(f"{path} is not a slippulse dynamic run with a checkpoint")
        if read_only(path):
            raise ValueError(f"--resume: {path} is read-only; a resume would modify it (make it "
                             "writable, or copy it and resume the copy)")
        work = path + ".partial"
        try:
            lock = cls._own(path)
        except SchemaError as exc:
            raise ValueError(f"--resume: {exc}") from None
        h5 = None
        try:
            shutil.copyfile(path, work)
            raw = GuardedFile(work, "r+b")
            h5 = h5py.File(raw, "r+")
            upgrade_v1(h5)
            cfg = _stored_config(h5, path)
            st = read_checkpoint(h5, path)
            raw.check()
        except BaseException as exc:
            try:
                if h5 is not None:
                    h5.close()
            except Exception:                    # noqa: BLE001 (discarded with the work file)
                pass
            _remove(work)
            lock.release()
            if isinstance(exc, OSError):
                raise OSError(exc.errno, exc.strerror or str(exc), work) from None
            if isinstance(exc, (KeyError, TypeError, AttributeError)):
                raise ValueError(f"--resume: {path}: not a complete run file ({exc})") from None
            raise
        return cls(path, raw, h5, lock), cfg, st

    def update_config(self, cfg: dict):
        """Store the resolved config of a resumed run (only RESUME_MUTABLE keys may differ)."""
        _store_config(self.h5, cfg)

    # ------------------------------------------------------------------ writing
    def record_step(self, stepper):
        """Buffer the per-step scalars (flushed to the file at each checkpoint)."""
        i = int(np.argmax(stepper.V))
        self._buf["step"].append(stepper.nstep)
        self._buf["t"].append(stepper.t)
        self._buf["dt"].append(stepper.dt_prev)
        self._buf["v_max"].append(stepper.V[i])
        self._buf["x_vmax"].append(stepper.x[i])
        self._buf["iters"].append(stepper.iters)

    def _flush_scalars(self):
        g = self.h5["scalars"]
        m = len(self._buf["step"])
        if m == 0:
            return
        n0 = g["step"].shape[0]
        for name, vals in self._buf.items():
            g[name].resize((n0 + m,))
            g[name][n0:] = np.asarray(vals)
            vals.clear()

    def check(self) -> None:
        """Raise the first write failure of the work file (a full disk) as an OSError naming
        it (:class:`~slippulse.core.guarded.GuardedFile`)."""
        self._raw.check()

    def snapshot(self, stepper):
        self.check()
        g = self.h5["snapshots"]
        n0 = g["step"].shape[0]
        for name in ("step", "t"):
            g[name].resize((n0 + 1,))
        g["step"][n0] = stepper.nstep
        g["t"][n0] = stepper.t
        for name in SNAP_FIELDS:
            g[name].resize((n0 + 1, stepper.n))
            g[name][n0] = getattr(stepper, name)

    def last_snapshot_step(self) -> int:
        s = self.h5["snapshots/step"]
        return int(s[-1]) if s.shape[0] else -1

    def checkpoint(self, stepper, status="running", message=""):
        """Write the solver state and publish FILE atomically (module docstring: close, rename,
        bring the previous FILE up to date as the next work file, reopen)."""
        self._flush_scalars()
        state = stepper.state()
        _write_checkpoint(self.h5, state, stepper.history_name)
        self.h5.attrs["status"] = status
        self.h5.attrs["message"] = message
        _kill_point("state_written")
        self.h5.close()
        self._raw.sync()
        self._raw.close()
        self._raw.check()                        # a full disk: FILE stays at its last checkpoint
        _kill_point("closed")
        prev = self.path + ".prev"
        with file_lock(self.path):
            if os.path.exists(prev):
                os.remove(prev)
            have_prev = False
            if os.path.exists(self.path):
                try:
                    os.link(self.path, prev)
                    have_prev = True
                except OSError:                  # no hard links here: copy after publishing
                    pass
            _kill_point("linked")
            os.replace(self.work, self.path)     # the commit point: FILE is the new checkpoint
            _kill_point("published")
        if have_prev:
            os.replace(prev, self.work)
            self._raw = GuardedFile(self.work, "r+b")
            self.h5 = h5py.File(self._raw, "r+")
            if _catch_up(self.h5, self.path, state, stepper.history_name):
                _kill_point("reopened")
                self.check()
                return
            self.h5.close()                      # previous FILE in another layout (resumed v1)
            self._raw.close()
        shutil.copyfile(self.path, self.work)
        self._raw = GuardedFile(self.work, "r+b")
        self.h5 = h5py.File(self._raw, "r+")
        self.check()

    def mark(self, status: str, message: str) -> None:
        """Record ``status`` and ``message`` in FILE after :meth:`close`, leaving its checkpoint
        as it is (a copy edited and renamed over FILE: an interrupted mark leaves FILE intact)."""
        def fill(h5):
            h5.attrs["status"] = status
            h5.attrs["message"] = message
        atomic_update(self.path, fill)

    def close(self, remove_work=True):
        """Close the work file (removing it with ``remove_work``) and release the run's lock.
        After a write failure the HDF5 objects are closed without flushing what cannot be
        written; nothing of the work file is used afterwards."""
        try:
            if self.h5.id.valid:
                self.h5.close()
        except Exception:                        # noqa: BLE001 (a failed disk: discarded below)
            if self._raw.error is None:
                raise
        finally:
            self._raw.close()
            if (remove_work or self._raw.error is not None) and os.path.exists(self.work):
                os.remove(self.work)
            if self._lock is not None:
                self._lock.release()
                self._lock = None


def _stored_config(h5, path: str) -> dict:
    """The resolved config stored in a run file (``/config`` attribute ``json``), checked: a
    table of tables (:class:`SchemaError` naming the file otherwise)."""
    from ..core import validate
    g = validate.member(h5, "config", path, h5py.Group)
    text = validate.text(g, "json", path)
    try:
        cfg = json.loads(text)
    except ValueError as exc:
        raise SchemaError(f"{path}: /config json is not valid JSON ({exc})") from None
    if not (isinstance(cfg, dict) and all(isinstance(v, dict) for v in cfg.values())):
        raise SchemaError(f"{path}: /config json is not a table of [section] tables")
    return cfg


def _store_config(h5, cfg: dict) -> None:
    gc = h5["config"]
    gc.attrs["json"] = json.dumps(cfg, sort_keys=True)
    for section, table in cfg.items():
        for key, val in table.items():
            gc.attrs[f"{section}.{key}"] = val


def _catch_up(work, path: str, state: dict, history_policy) -> bool:
    """Make the work file (the previous FILE) hold what FILE holds: append the snapshot and
    scalar rows it lacks (read from FILE), rewrite the checkpoint from ``state``, copy the root
    status and the config. Returns False (work untouched) when the two are not in the same
    layout version (the caller then copies FILE)."""
    with open_h5(path) as src:
        if format_version(work, path) != format_version(src) or "x" not in work:
            return False
        for gname in ("snapshots", "scalars"):
            gs, gw = src[gname], work[gname]
            n_new, n_old = gs["step"].shape[0], gw["step"].shape[0]
            if n_new == n_old:
                continue
            for name, ds in gs.items():
                tail = ds[n_old:n_new]
                gw[name].resize((n_new,) + ds.shape[1:])
                gw[name][n_old:n_new] = tail
        for key in ("status", "message"):
            work.attrs[key] = src.attrs[key]
        for key, val in src["config"].attrs.items():
            work["config"].attrs[key] = val
    _kill_point("rows_caught_up")
    _write_checkpoint(work, state, history_policy)
    return True


def read_checkpoint(h5: h5py.File, path: str = "") -> dict:
    """The checkpoint state dict (as written by PredictorCorrector.state()); dimension scales
    are not part of it. Validated: no external or dangling link, finite numbers only
    (:class:`SchemaError` naming the file and the dataset)."""
    from ..core import validate
    path = path or h5.filename
    g = validate.member(h5, "checkpoint", path, h5py.Group)
    st = {}
    names = []
    g.visit_links(names.append) if hasattr(g, "visit_links") else g.visit(names.append)
    for name in names:
        parent, _, leaf = name.rpartition("/")
        obj = validate.member(g[parent] if parent else g, leaf, path)
        if isinstance(obj, h5py.Dataset) and not obj.is_scale:
            if obj.dtype.kind == "b":
                st[name] = obj[()]
            else:
                validate.real_array(obj, path, ndim=None, complex_ok=True)
                st[name] = obj[()]
    return st


def _remove(p: str) -> None:
    try:
        os.remove(p)
    except FileNotFoundError:
        pass
