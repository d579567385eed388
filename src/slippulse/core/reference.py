"""Reference values that the code draws but does not compute, read from data files with provenance.

Each file under ``slippulse/data`` names its source in a ``[source]`` table (a paper's figure or
equation, or the command and commit of one of our runs) and holds the numbers in ``[values]``.
"""
from __future__ import annotations

import os
import tomllib
from functools import lru_cache

#: Folder of the package's data files.
DATA_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "data")


@lru_cache(maxsize=None)
def load(name: str) -> dict:
    """The parsed data file ``slippulse/data/<name>.toml`` (tables ``source`` and ``values``).

    Raises
    ------
    FileNotFoundError
        No such data file.
    ValueError
        The file lacks its ``[source]`` (provenance) or ``[values]`` table.
    """
    with open(os.path.join(DATA_DIR, name + ".toml"), "rb") as fh:
        data = tomllib.load(fh)
    for table in ("source", "values"):
        if not isinstance(data.get(table), dict):
            raise ValueError(f"data file {name}.toml: no [{table}] table")
    return data


def paper_scaling() -> dict:
    """The paper's scaling-theory constants (Eqs. 3–4): ``{"tau_star", "a_v", "a_G"}`` as floats.

    Source and provenance: ``slippulse/data/paper_scaling.toml``.
    """
    v = load("paper_scaling")["values"]
    return {k: float(v[k]) for k in ("tau_star", "a_v", "a_G")}
