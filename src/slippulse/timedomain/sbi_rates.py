"""Growth rates the SBI measured, to set beside the linear spectrum
(``slippulse dynamic spectrum-report``): those of a rates file (a table of measured values with its
provenance, e.g. dynamic/results/sbi_growth_rates.toml) and those of a scan's finished ±ε pairs,
computed from their runs (:func:`.perturbation.pair_growth`, with the pair's mode shape)."""
from __future__ import annotations

import math
import tomllib

from .perturbation import pair_growth, pair_rows, read_series, scan_rows


def read_sbi_rates(path: str) -> list[dict]:
    """The ``[[rates]]`` tables of a rates file: tau_d_ratio, s (per pulse length), err, domain
    (the SBI period and grid, words). Raises ValueError naming the file and the missing key, or
    when the file has no ``[source]`` table (a measured value without provenance)."""
    with open(path, "rb") as fh:
        data = tomllib.load(fh)
    if "source" not in data:
        raise ValueError(f"{path}: no [source] table (where the rates were measured)")
    out = []
    for i, r in enumerate(data.get("rates", [])):
        try:
            out.append({"tau_d_ratio": float(r["tau_d_ratio"]), "s": float(r["s"]),
                        "err": float(r["err"]), "domain": str(r["domain"])})
        except KeyError as exc:
            raise ValueError(f"{path}: [[rates]] table {i + 1} has no {exc.args[0]!r}") from None
    return out


def scan_pair_rates(scan) -> list[dict]:
    """The growth rate of each finished ±ε pair of ``scan`` (:class:`.scan.Scan`) with a finite
    rate: tau_d_ratio, s and err (per pulse length, :func:`.perturbation.pair_growth`), domain
    (period and ε, words), mode and mode_xi (the antisymmetric deviation of ln(v/v*+1) and its
    (ξ − ξ_front)/L⁰, None where the fit gives none)."""
    out = []
    for plus, minus in pair_rows(scan_rows(scan)):
        eps = abs(float(plus["eps"]))
        g = pair_growth(read_series(plus["file"]), read_series(minus["file"]), eps)
        if not math.isfinite(g.get("s_per_L", math.nan)):
            continue
        out.append({"tau_d_ratio": float(plus["tau_d_ratio"]), "s": float(g["s_per_L"]),
                    "err": float(g["s_per_L_err"]),
                    "domain": f"{float(plus.get('behind', 3.0)):g}+"
                              f"{float(plus.get('ahead', 2.0)):g} L, ε = {eps:g}",
                    "mode": g.get("mode"), "mode_xi": g.get("mode_xi")})
    return out
