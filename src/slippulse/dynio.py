"""HDF5 output of dynamic runs: snapshots, per-step scalars, checkpoints, bit-exact resume.

Layout::

    /                 attrs: slippulse_version, created, kind="dynamic", status, message
    /parameters       attrs: the Table-I parameters (SI) + units_<name>
    /config           attrs: toml-like "section.key" = value (the resolved config), json (all of it)
    /grid/x           (N,) m
    /snapshots/step   (nt,)        resizable time axis; V (nt, N) m/s, phi s, tau Pa, delta m, t s
    /scalars/step     (ns,)        per step: t (s), dt (s), v_max (m/s), x_vmax (m), iters (1)
    /checkpoint       the full solver state at the last checkpoint (arrays and attrs t, nstep)

Crash safety: the run writes into ``FILE.partial``; at each checkpoint that file is closed, copied
to ``FILE.tmp`` and renamed over ``FILE`` (``os.replace`` is atomic). ``FILE`` is therefore always
a complete file as of the last checkpoint, whatever happens to the process. ``--resume`` copies
``FILE`` back to ``FILE.partial`` and continues from its checkpoint; the results are bit-identical
to an uninterrupted run because the checkpoint holds every array the next step reads.
"""
from __future__ import annotations

import datetime as _dt
import json
import os
import shutil

import h5py
import numpy as np

from . import __version__
from .params import Parameters

SNAP_FIELDS = {"V": "m/s", "phi": "s", "tau": "Pa", "delta": "m"}
SCALARS = {"t": "s", "dt": "s", "v_max": "m/s", "x_vmax": "m", "iters": "1"}


class RunFile:
    """Writer of one dynamic run (see module docstring)."""

    def __init__(self, path: str, h5: h5py.File):
        self.path = path
        self.work = path + ".partial"
        self.h5 = h5
        self._buf = {k: [] for k in ("step", *SCALARS)}

    # ------------------------------------------------------------------ creation / resume
    @classmethod
    def create(cls, path: str, cfg: dict, params: Parameters, stepper) -> "RunFile":
        work = path + ".partial"
        h5 = h5py.File(work, "w")
        h5.attrs["slippulse_version"] = __version__
        h5.attrs["created"] = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
        h5.attrs["kind"] = "dynamic"
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
        gg = h5.create_group("grid")
        gg.create_dataset("x", data=stepper.x).attrs["units"] = "m"
        n = stepper.n
        gs = h5.create_group("snapshots")
        gs.create_dataset("step", shape=(0,), maxshape=(None,), dtype="i8")
        gs.create_dataset("t", shape=(0,), maxshape=(None,), dtype="f8").attrs["units"] = "s"
        for name, unit in SNAP_FIELDS.items():
            ds = gs.create_dataset(name, shape=(0, n), maxshape=(None, n), dtype="f8",
                                   chunks=(1, n))
            ds.attrs["units"] = unit
        gsc = h5.create_group("scalars")
        gsc.create_dataset("step", shape=(0,), maxshape=(None,), dtype="i8", chunks=(4096,))
        for name, unit in SCALARS.items():
            dtype = "i8" if name == "iters" else "f8"
            gsc.create_dataset(name, shape=(0,), maxshape=(None,), dtype=dtype,
                               chunks=(4096,)).attrs["units"] = unit
        return cls(path, h5)

    @classmethod
    def open_resume(cls, path: str) -> tuple["RunFile", dict, dict]:
        """Reopen FILE for appending; returns (writer, stored config, checkpoint state)."""
        if not os.path.exists(path):
            raise FileNotFoundError(f"--resume: output file {path} does not exist")
        work = path + ".partial"
        shutil.copyfile(path, work)
        h5 = h5py.File(work, "r+")
        if h5.attrs.get("kind") != "dynamic" or "checkpoint" not in h5:
            h5.close()
            raise ValueError(f"{path} is not a slippulse dynamic run with a checkpoint")
        cfg = json.loads(h5["config"].attrs["json"])
        st = read_checkpoint(h5)
        return cls(path, h5), cfg, st

    def update_config(self, cfg: dict):
        """Store the resolved config of a resumed run (only RESUME_MUTABLE keys may differ)."""
        gc = self.h5["config"]
        gc.attrs["json"] = json.dumps(cfg, sort_keys=True)
        for section, table in cfg.items():
            for key, val in table.items():
                gc.attrs[f"{section}.{key}"] = val

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

    def snapshot(self, stepper):
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
        """Write the solver state and publish FILE atomically (close, copy, rename, reopen)."""
        self._flush_scalars()
        if "checkpoint" in self.h5:
            del self.h5["checkpoint"]
        g = self.h5.create_group("checkpoint")
        for key, val in stepper.state().items():
            g.create_dataset(key, data=np.asarray(val))   # 0-d datasets for scalars: exact
        g.attrs["history_policy"] = stepper.history_name
        self.h5.attrs["status"] = status
        self.h5.attrs["message"] = message
        self.h5.close()
        tmp = self.path + ".tmp"
        shutil.copyfile(self.work, tmp)
        os.replace(tmp, self.path)
        self.h5 = h5py.File(self.work, "r+")

    def close(self, remove_work=True):
        self.h5.close()
        if remove_work and os.path.exists(self.work):
            os.remove(self.work)


def read_checkpoint(h5: h5py.File) -> dict:
    """The checkpoint state dict (as written by PredictorCorrector.state())."""
    g = h5["checkpoint"]
    st = {}

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset):
            st[name] = obj[()]
    g.visititems(visit)
    return st
