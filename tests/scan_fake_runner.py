"""A small runner following the scan contract (slippulse.timedomain.scan), for tests/test_scan.py.

``run_case`` sleeps ``case["sleep"]`` s (default 0.1), appends ``<pid> <eps>`` to ``case["log"]``
(so tests count the runs), raises if ``case["fail"]`` is true, and writes an HDF5 file with the
attributes ``complete`` and ``case_json``, plus the row as attributes (atomically: temp + replace).
"""
from __future__ import annotations

import json
import os
import time

import h5py

ROW_KEYS = ("growth", "fate", "n_steps", "stable")


def _row(case: dict) -> dict:
    eps = float(case.get("eps", 0.0))
    return {"growth": 10.0 * eps, "fate": "grows" if eps > 0 else "decays",
            "n_steps": int(1000 * abs(eps)) + 1, "stable": eps <= 0}


def run_case(case: dict, out_path: str) -> dict:
    time.sleep(float(case.get("sleep", 0.1)))
    if "log" in case:
        with open(case["log"], "a") as fh:
            fh.write(f"{os.getpid()} {case.get('eps')}\n")
    if case.get("fail"):
        raise RuntimeError(f"case with eps={case.get('eps')} asked to fail")
    row = _row(case)
    tmp = out_path + ".part"
    with h5py.File(tmp, "w") as h5:
        for k, v in row.items():
            h5.attrs[k] = v
        h5.attrs["case_json"] = json.dumps(case, sort_keys=True)
        h5.attrs["complete"] = True
    os.replace(tmp, out_path)
    return row


def read_row(out_path: str) -> dict:
    with h5py.File(out_path, "r") as h5:
        out = {k: h5.attrs[k] for k in ROW_KEYS}
    out["fate"] = str(out["fate"])
    return out


def scan_figures(rows: list[dict], out_dir: str) -> list[str]:
    path = os.path.join(out_dir, "figure.txt")
    with open(path, "w") as fh:
        fh.write("\n".join(f"{r['id']} {r['status']}" for r in rows) + "\n")
    return [path]
