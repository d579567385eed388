"""The divergence analysis of a deep family (steady.divergence, `slippulse steady divergence`):
exact power laws are recovered, tables and files join as one family, bad input exits 2."""
import csv

import numpy as np
import pytest

from slippulse.cli.app import main
from slippulse.core.params import DEFAULT
from slippulse.steady import divergence as dv

TAU_STAR, M_L, M_B = 1.0071, 2.5, 1.5


def _write_table(path, q, passed=True):
    d = q - TAU_STAR
    L = 3.0 * d ** (-M_L)
    beta = 1.0 - 40.0 * d ** M_B
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["label", "tau_d_ratio", "beta", "L", "n_points", "continuation",
                    "grid_check_passed", "grid_check_n", "grid_check_n_fine", "grid_check_dbeta",
                    "grid_check_dL_rel"])
        for k, (qq, bb, LL) in enumerate(zip(q, beta, L)):
            w.writerow([f"p{k}", repr(float(qq)), repr(float(bb)), repr(float(LL)), 2000, "arclength",
                        str(passed), 2000, 3999, 1e-9, 1e-6])
    return L


def test_exact_power_law_recovers_tau_star_and_exponents(tmp_path):
    q = TAU_STAR + np.geomspace(2e-4, 2e-2, 60)
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    _write_table(a, q[:35])
    _write_table(b, q[30:])                       # overlapping rows are taken once
    pts = dv.read_points(tables=[str(a), str(b)])
    assert len(pts) == 60 and np.all(np.diff(pts.q) < 0)
    dec = dv.deepest_decade(pts, DEFAULT)
    for key in ("both", "L", "beta"):
        assert dec["fits"][key]["tau_star"] == pytest.approx(TAU_STAR, abs=1e-8)
    assert dec["fits"]["both"]["m_L"] == pytest.approx(M_L, rel=1e-6)
    assert dec["fits"]["both"]["m_beta"] == pytest.approx(M_B, rel=1e-6)
    assert dec["tau_star"] == pytest.approx(TAU_STAR, abs=1e-8)
    assert dec["tau_star_err"] < 1e-7
    loc = dv.local_exponents(pts, TAU_STAR)
    # on exact power laws the centred log-differences are exact
    assert np.allclose(loc["m"], M_L, rtol=1e-9)
    assert np.allclose(loc["r"], M_L / M_B, rtol=1e-9)
    assert np.all(np.diff(loc["L"]) > 0)


def test_two_laws_with_different_tau_star_give_a_spread(tmp_path):
    """L diverging at one τ̃* and 1 − β at another: the joint fit lies between, and the stated
    uncertainty covers both."""
    q = 1.0080 + np.geomspace(1e-4, 1e-2, 50)
    L = 3.0 * (q - 1.0070) ** (-2.5)
    beta = 1.0 - 40.0 * (q - 1.0066) ** 1.5
    pts = dv.FamilyPoints(q=q[::-1], beta=beta[::-1], L=L[::-1], n_points=np.full(50, 2000),
                          arclength=np.ones(50, bool))
    dec = dv.deepest_decade(pts, DEFAULT)
    assert dec["fits"]["L"]["tau_star"] == pytest.approx(1.0070, abs=1e-7)
    assert dec["fits"]["beta"]["tau_star"] == pytest.approx(1.0066, abs=1e-7)
    assert dec["tau_star_err"] == pytest.approx(0.0002, abs=1e-6)


def test_unchecked_rows_are_left_out_and_too_few_pulses_refused(tmp_path):
    q = TAU_STAR + np.geomspace(1e-3, 2e-2, 4)
    _write_table(tmp_path / "bad.csv", q, passed=False)
    with pytest.raises(Exception, match="no converged pulse"):
        dv.read_points(tables=[str(tmp_path / "bad.csv")])
    _write_table(tmp_path / "few.csv", q)
    with pytest.raises(ValueError, match="deepest decade"):
        dv.deepest_decade(dv.read_points(tables=[str(tmp_path / "few.csv")]), DEFAULT)


def test_cli_summary_states_tau_star_with_its_uncertainty(tmp_path, capsys):
    q = TAU_STAR + np.geomspace(2e-4, 2e-2, 60)
    _write_table(tmp_path / "t.csv", q)
    fig = tmp_path / "d.png"
    assert main(["steady", "divergence", "--table", str(tmp_path / "t.csv"),
                 "--figure", str(fig), "--exponents-figure", str(tmp_path / "e.png")]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert "tau_star = 1.0071 ± 0.0000" in last and "60 pulses" in last
    assert fig.stat().st_size > 0 and (tmp_path / "e.png").stat().st_size > 0


@pytest.mark.parametrize("argv, word", [
    ([], "FILE"),
    (["--table", "nowhere.csv"], "--table"),
    (["--table", "TABLE", "--figure", "x.nope"], "--figure"),
])
def test_cli_bad_input_exits_2(tmp_path, capsys, argv, word):
    _write_table(tmp_path / "t.csv", TAU_STAR + np.geomspace(2e-4, 2e-2, 20))
    argv = [str(tmp_path / "t.csv") if a == "TABLE" else a for a in argv]
    assert main(["steady", "divergence", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and word in err[0]


def test_cli_table_without_columns_exits_2(tmp_path, capsys):
    (tmp_path / "t.csv").write_text("a,b\n1,2\n")
    assert main(["steady", "divergence", "--table", str(tmp_path / "t.csv")]) == 2
    assert "tau_d_ratio" in capsys.readouterr().err


SEED = "steady/seeds/seed_2550m.h5"


def test_edges_of_a_committed_seed(capsys):
    """The seed's pulse (L = 2.49 km): a Lorentz-contracted leading edge of 80-83 mm and a
    healing e-fold of 0.66 m (docs/results.md); the longest pulse is at distance 0 from itself."""
    from slippulse.core.h5io import list_pulses, read_pulse
    from slippulse.steady.edges import edge_study

    read = [read_pulse(SEED, lab) for lab in list_pulses(SEED)]
    rows = edge_study([p for p, _ in read], read[0][1])
    p, e = rows[-1]
    g = (1 - p.beta ** 2) ** 0.5
    assert 0.078 < e["ell"] / g < 0.085
    assert 0.6 < e["back_efold"] < 0.7
    assert e["front_dist"] == 0.0 and e["back_dist"] == 0.0
    with pytest.raises(ValueError, match="no pulse"):
        edge_study([], DEFAULT)


def test_edges_cli_bad_figure_exits_2(capsys):
    assert main(["steady", "edges", SEED, "--figure", "x.nope"]) == 2
    assert "--figure" in capsys.readouterr().err


def test_seed_copies_the_deepest_pulses_and_tables_them(tmp_path, capsys):
    """`steady seed`: the deepest pulse of a seed file copied into a new one; its table read back
    by `read_points` gives the same (τ_d, β, L); a second write to the same seed exits 2."""
    from slippulse.core.h5io import list_pulses, read_pulse

    src = "steady/seeds/seed_9473m.h5"
    out, table = tmp_path / "s.h5", tmp_path / "t.csv"
    assert main(["steady", "seed", src, str(out), "--keep", "1", "--table", str(table)]) == 0
    labs = list_pulses(str(out))
    deepest = read_pulse(src, list_pulses(src)[-1])[0]
    assert labs == [deepest.label]
    pts = dv.read_points(tables=[str(table)])
    assert pts.q.min() == deepest.tau_d_ratio and pts.L[-1] == deepest.L
    assert main(["steady", "seed", src, str(out)]) == 2
    assert main(["steady", "seed", src, str(tmp_path / "x.h5"), "--keep", "0"]) == 2
