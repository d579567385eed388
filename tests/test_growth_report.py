"""``slippulse dynamic growth-report`` (cli/growth.py) and its figure of the measured rates
(plotting.stability.growth_figure)."""
import math

from cli_inproc import run as cli
from slippulse.plotting.stability import growth_figure


def _scan_toml(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(f'[scan]\nname = "s"\nout_dir = "{tmp_path / "s"}"\n'
                    '[grid]\neps = [1e-3, -1e-3]\n')
    return path


def test_growth_figure_draws_the_finite_rates(tmp_path):
    pairs = [dict(tau_d_ratio=t, s_per_L=s, s_per_L_err=0.01, s_per_s=100 * s, s_per_s_err=1.0,
                  variant=v) for t, s, v in ((1.2, -0.1, "base"), (1.1, 0.2, "base"),
                                             (1.1, 0.21, "ε = 0.01"), (1.05, math.nan, "base"))]
    out = growth_figure(pairs, str(tmp_path / "g.png"))
    assert out == str(tmp_path / "g.png") and (tmp_path / "g.png").stat().st_size > 1000


def test_a_scan_without_finished_cases_is_reported_and_draws_nothing(tmp_path):
    r = cli(["dynamic", "growth-report", _scan_toml(tmp_path), "--figdir", tmp_path / "f"])
    assert r.returncode == 0, r.stderr
    assert "(no results for s)" in r.stdout and "0 pairs of 1 scans: no figures" in r.stdout
    assert not (tmp_path / "f").exists()


def test_a_missing_family_file_is_refused_with_one_line(tmp_path):
    r = cli(["dynamic", "growth-report", _scan_toml(tmp_path), "--family", tmp_path / "no.h5",
             "--figdir", tmp_path / "f"])
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "--family" in r.stderr
