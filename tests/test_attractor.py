"""The steady line as attractor (timedomain/attractor.py, ``slippulse dynamic attractor``): the
antisymmetric response of a ±ε pair, the departure fraction, a run's distance from the steady
line, the overlap table; the command's refusals and its run on a pulse with a stored mode."""
import math

import numpy as np
import pytest

from cli_inproc import run as cli
from slippulse.timedomain.attractor import (OVERLAP_COLUMNS, departure_fraction, line_departure,
                                            pair_response, read_overlap_csv, write_overlap_csv)

L0, C0 = 1.2, 150.0                         # m, m/s: the steady pulse of the synthetic runs


def _pair(sigma, eps=1e-3, k_front=0.4, k_length=-0.05, n=200, t_end=None):
    """A ±ε pair whose antisymmetric parts are exactly eps e^{σt} (v_max error), k_front times
    it (front position, m) and k_length times it (L/L⁰), over symmetric (quadratic) parts that
    the pair must cancel."""
    t = np.linspace(0.0, t_end or 5.0 / sigma, n)
    r = eps * np.exp(sigma * t)
    sym = 3.0 * r ** 2 + 1e-4 * np.sin(40 * t)
    out = []
    for sign in (1, -1):
        out.append({"t": t, "v_max_error": sign * r + sym,
                    "x_front": C0 * t + sign * k_front * r + 0.01 * sym,
                    "L": L0 * (1.0 + sign * k_length * r + sym),
                    "attrs": {"L": L0, "c_p": C0, "beta": 0.05}})
    return out


def test_pair_response_recovers_rate_and_amplitude_ratios():
    sigma = 60.0
    plus, minus = _pair(sigma)
    g = pair_response(plus, minus)
    s_per_L = sigma * L0 / C0
    assert g["s_fit_all"] == pytest.approx(s_per_L, rel=1e-9)
    assert g["s_fit_first_third"] == pytest.approx(s_per_L, rel=1e-9)
    assert g["k_front"] == pytest.approx(0.4, rel=1e-9)
    assert g["k_length"] == pytest.approx(-0.05, rel=1e-9)
    # the regime ends at the first sample where either run's |v_max error| passes 0.03
    big = np.maximum(np.abs(plus["v_max_error"]), np.abs(minus["v_max_error"]))
    i1 = int(np.nonzero(big > 0.03)[0][0])
    assert g["d_end"] == pytest.approx(plus["t"][i1 - 1] * C0 / L0)


def test_pair_response_without_a_linear_regime_is_refused():
    plus, minus = _pair(60.0, eps=0.05)              # past the bound from the start
    with pytest.raises(ValueError, match="linear regime"):
        pair_response(plus, minus)


def test_departure_fraction_is_zero_along_the_line_and_one_at_fixed_length():
    assert departure_fraction(2.0, 0.5, 1.0) == pytest.approx(0.0)    # δln c = 2 δln L: the line
    assert departure_fraction(2.0, 0.0, 1.0) == pytest.approx(1.0)    # L unchanged
    assert departure_fraction(2.0, -0.5, 1.0) == pytest.approx(2.0)   # L and c_p opposite
    assert math.isnan(departure_fraction(2.0, 0.5, 0.0))


def test_line_departure_measures_the_relative_distance_from_a_power_law_line():
    """Line c_p⁰(L) = c (L/1 m)^0.5 through four pulses; a run at 2 % above it over L ∈ [2, 3] m
    (exact: the line is linear in ln L − ln c_p), then 20 % of its samples beyond the line's range."""
    Ls = np.array([1.0, 2.0, 4.0, 8.0])
    curve = np.column_stack([Ls, 100 * Ls ** 0.5, 1.2 - 0.01 * np.arange(4), 0.04 * Ls ** 0.5])
    n = 100
    d = np.linspace(0.0, 2.0, n)
    L = np.where(np.arange(n) < 80, 2.5, 20.0)
    c = 1.02 * 100 * np.minimum(L, 8.0) ** 0.5
    c[80:] = c[79]
    s = {"distance": d, "L": L, "c_p": c, "attrs": {"c_p": c[0], "beta": 0.05}}
    r = line_departure(s, curve)
    assert r["median"] == pytest.approx(0.02, rel=1e-9)
    assert r["L_min"] == 2.5 and r["L_max"] == 20.0
    kept = (d >= 0.1) & (np.arange(n) >= 2) & (np.arange(n) < n - 2)
    assert r["fraction"] == pytest.approx(np.mean(L[kept] <= 8.0))
    with pytest.raises(ValueError, match="no sample"):
        line_departure(dict(s, distance=np.zeros(n)), curve)


def test_overlap_table_round_trips_and_a_foreign_table_is_refused(tmp_path):
    rows = [dict({k: 0.5 + i for k in OVERLAP_COLUMNS}, label=f"td1.{i}", tau_d_ratio=1.2 - 0.1 * i)
            for i in range(3)]
    path = write_overlap_csv(rows, str(tmp_path / "o.csv"))
    back = read_overlap_csv(path)
    assert [r["label"] for r in back] == ["td1.2", "td1.1", "td1.0"]      # by increasing τ_d
    assert back[0]["overlap"] == 2.5
    (tmp_path / "x.csv").write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match="not an overlap table"):
        read_overlap_csv(str(tmp_path / "x.csv"))


@pytest.mark.parametrize("argv, word", [
    (["overlap", "{tmp}/no.h5"], "FAMILY"),
    (["overlap", "{st}", "--local-h", "0"], "--local-h"),
    (["overlap", "{st}", "--local-h", "nan"], "--local-h"),
    (["overlap", "{st}", "--labels", "td9.9999"], "--labels"),
    (["overlap", "{st}", "--figure", "{tmp}/f.xyz"], "--figure"),
    (["overlap", "{st}", "--pairs", "{tmp}/nodir"], "--pairs"),
    (["pairs", "{tmp}/nodir"], "DIR"),
    (["pairs", "{tmp}", "--d-max", "2"], "--d-max"),
    (["figure", "{tmp}/f.png", "--csv", "{tmp}/no.csv"], "--csv"),
    (["figure", "{tmp}/f.png", "--csv", "{tmp}/bad.csv"], "not an overlap table"),
])
def test_bad_input_is_one_line_exit_2(tmp_path, steady12_with_spectrum, argv, word):
    (tmp_path / "bad.csv").write_text("a,b\n1,2\n")
    args = [a.format(tmp=tmp_path, st=steady12_with_spectrum) for a in argv]
    r = cli(["dynamic", "attractor", *args])
    assert r.returncode == 2, r.stdout + r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and word in r.stderr


def test_overlap_of_the_1p2_pulse_against_its_own_tangent(tmp_path, steady12_with_spectrum):
    """The 1.2 τ_min pulse with its stored mode and its tangent from τ_d ± 2e-3 solved on its grid:
    a row whose departure fraction follows from its own columns, the table and the figure; the
    label filter keeps the pulse."""
    out = tmp_path / "o.csv"
    fig = tmp_path / "o.png"
    r = cli(["dynamic", "attractor", "overlap", steady12_with_spectrum, "--local-h", "2e-3",
             "--labels", "td1.2000", "--csv", out, "--figure", fig])
    assert r.returncode == 0, r.stderr
    (row,) = read_overlap_csv(str(out))
    assert row["label"] == "td1.2000" and 0.0 <= row["overlap"] <= 1.0
    assert row["departure_fraction"] == pytest.approx(
        departure_fraction(row["line_slope"], row["dL_over_L"], row["dc_over_c"]))
    # the 1.2 pulse's mode changes c_p much more than L (docs/stability.md §4: f ≈ 1 there)
    assert abs(row["dc_over_c"]) > 5 * abs(row["dL_over_L"])
    assert fig.stat().st_size > 1000


def test_figure_from_overlap_tables_with_named_series(tmp_path):
    """``attractor figure`` draws several tables, one name each; more names than tables is
    refused before any drawing."""
    rows = [dict({k: 0.5 for k in OVERLAP_COLUMNS}, label=f"td{q}", tau_d_ratio=q,
                 departure_fraction=0.2 * i) for i, q in enumerate((1.05, 1.1, 1.2))]
    a = write_overlap_csv(rows, str(tmp_path / "a.csv"))
    b = write_overlap_csv(rows[:2], str(tmp_path / "b.csv"))
    out = tmp_path / "f.png"
    r = cli(["dynamic", "attractor", "figure", out, "--csv", a, b, "--names", "N=2000", "N=3000"])
    assert r.returncode == 0, r.stderr
    assert out.stat().st_size > 1000
    r = cli(["dynamic", "attractor", "figure", tmp_path / "g.png", "--csv", a, "--names", "x", "y"])
    assert r.returncode == 2 and "--names" in r.stderr and not (tmp_path / "g.png").exists()
