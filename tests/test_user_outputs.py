"""What a user sees: each figure drawn or refused with a reason, and summary lines that say what
happened, with their uncertainty or the words that they have none."""
import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cli_inproc  # noqa: E402


def _rated_family(path):
    from test_law import _family_with_rates
    return _family_with_rates(path, lambda r: 8.8e3 * (r - 1.0077) ** 3)


def test_rates_figure_is_drawn_when_tau_star_cannot_be_fitted(tmp_path):
    """Three rated pulses below --below: too few for the shifted fit (four), enough for the
    others; the figure is drawn against tau_d/tau_min - 1 and the output says so."""
    f = str(tmp_path / "fam.h5")
    _rated_family(f)
    png = tmp_path / "rates.png"
    r = cli_inproc.run(["steady", "rates", f, "--below", "1.02", "--figure", str(png)])
    assert r.returncode == 0, r.stderr
    assert png.exists() and png.stat().st_size > 10_000
    assert "3 of the 7 rated pulses are fitted" in r.stdout
    assert "no tau_star" in r.stdout and "panel (a) is drawn against tau_d/tau_min - 1" in r.stdout


def test_rates_say_which_pulses_below_excluded(tmp_path):
    """--below that leaves no rated pulse: the output names the window, not a bare 'got 0'."""
    f = str(tmp_path / "fam.h5")
    _rated_family(f)
    r = cli_inproc.run(["steady", "rates", f, "--below", "1.01"])
    assert r.returncode == 0, r.stderr
    assert "0 of the 7 rated pulses are fitted" in r.stdout and "--below 1.01" in r.stdout
    assert "got 0" not in r.stdout and "0 pulses to fit, a fit needs 3" in r.stdout


@pytest.mark.parametrize("args, flag", [(["--to", "1.3"], "--to=1.3"), (["--to", "0.5"], "--to=0.5"),
                                        (["--from", "1.5"], "--from=1.5")])
def test_family_bad_input_is_one_line_naming_the_flag_and_no_bar(tmp_path, args, flag):
    """Refused before any work: exit 2, the flag as the user typed it, no progress-bar stub."""
    import subprocess
    r = subprocess.run([sys.executable, "-m", "slippulse", "steady", "family", "--out",
                        str(tmp_path / "f.h5"), *args], capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [r.stderr.strip()]          # one line
    assert flag in r.stderr and "family:" not in r.stderr and "%|" not in r.stderr


def test_family_progress_counts_whole_targets():
    """The bar shows targets passed as an integer (it showed 8.0/31); the position between
    targets still moves (the postfix names the pulse)."""
    from types import SimpleNamespace

    from tqdm import tqdm

    from slippulse.cli.steady import FamilyProgress
    prog = FamilyProgress(1.2, 1.05, 0.005)
    bar = tqdm(total=prog.total, disable=True)
    prog.bar = bar
    prog(1.165, SimpleNamespace(tau_d_ratio=1.1625, beta=0.3, L=2.0), "beta-step")
    assert isinstance(bar.n, int) and bar.n == 8 and prog.position == pytest.approx(8.5)


def test_family_and_stability_summaries_count_in_words():
    from types import SimpleNamespace

    from slippulse.cli.steady import family_summary, final_status
    rep = SimpleNamespace(written=["a"] * 31, reached=1.05, attempts=31, failures=[],
                          wall_time=10.0, checks=31, failed_checks=[], reached_L=3.0,
                          limit_reached=False, stopped_early=False)
    line = final_status(rep, 1.2, 1.05, "f.h5")
    assert "31 grid checks, all passed" in line and "written as failed" not in line
    rep.failed_checks = ["x", "y"]
    assert "2 failed (those pulses written, marked failed)" in final_status(rep, 1.2, 1.05, "f")
    rep = SimpleNamespace(skipped=[], failed=[], wall_time=1.0)
    line = family_summary("f.h5", [SimpleNamespace(refined=None, sigmas=(), count=None)], rep)
    assert "1 pulse solved, none failed" in line and "0 kept" not in line


def _short_run(s_true, s_meas_growth, s_err):
    """A verify result over 0.1 L whose |v_max error| grows as e^(s_meas_growth d) in the fit
    window, the pulse's stored eigenvalue s_true ± s_err."""
    import numpy as np

    from slippulse.timedomain.verify import SERIES, VerifyResult, growth_rate
    d = np.linspace(0.0, 0.1, 21)
    err = 1e-3 * np.exp(s_meas_growth * d)
    series = {k: np.zeros_like(d) for k in SERIES}
    series.update(v_max_error=err, distance=d)
    info = {"travelled": 0.1, "status": "finished", "eigen_s_per_L": s_true,
            "eigen_s_err_per_L": s_err, "eigen_translation_s_per_L": 1e-6,
            "eigen_source": "stored in f.h5", "growth_rate_v_max": growth_rate(d, err)}
    return VerifyResult(t=d, x_front=d, series=series, errors={}, info=info)


def test_verify_verdict_agrees_with_the_growth_its_figure_draws():
    """The mode grows by e^0.8 over the run and the drift grows at its rate: the verdict says so
    (it said 'the drift is not its growth'), leaves it unattributed as too short, and quotes the
    eigenvalue with its stored s_err."""
    from slippulse.timedomain.verify import drift_verdict, mode_growth
    res = _short_run(8.0, 8.0, 0.02)
    assert mode_growth(res.info)[1] == 0.02
    verdict, text = drift_verdict(res)
    assert verdict is None
    assert "not its growth" not in text and "as the unstable mode s = 8 ± 0.02 per L" in text
    assert "e^0.80" in text and "too little to attribute" in text
    verdict, text = drift_verdict(_short_run(8.0, 30.0, 0.02))
    assert verdict is None and "not as the unstable mode" in text


def test_steady_solve_and_verify_lines_say_they_carry_no_error_estimate(pulse12):
    from slippulse.cli.steady import summary_line
    from slippulse.core.params import DEFAULT
    from slippulse.timedomain.verify import summary
    assert "no error estimate" in summary_line(pulse12.to_pulse(), DEFAULT)
    res = _short_run(8.0, 8.0, 0.02)
    res.errors.update(c_p_error=1e-4, v_max_error=2e-3, L_error=1e-4, lnv_error=1e-3)
    res.info.update(tau_d_ratio=1.1, n_steps=10, wall_time=1.0, n=4096, dx=1e-3)
    assert "no error estimate" in summary(res)


def test_analyse_table_says_why_zeta_or_its_error_is_missing():
    """Rows whose ζ could not be fitted, or whose ζ has no error (no window variant on the grid),
    get one line per reason naming them, and the table says which columns have no uncertainty."""
    import math

    from slippulse.steady.analysis_table import format_table
    base = dict(beta=0.5, c_p=1.0, L=1.0, L_tilde=1.0, v_max=1.0, tau_max=1.0, tau_m_pulse=1.0,
                total_slip=1.0, G_bar_max=1.0, max_residual=1e-15)
    rows = [dict(base, label=f"td1.{k:04d}", zeta=0.5, zeta_err=math.nan,
                 zeta_note="no variant of the fit window lies on the grid") for k in range(14)]
    rows.append(dict(base, label="td1.2000", zeta=math.nan, zeta_err=math.nan,
                     zeta_note="edge-fit window is empty"))
    rows.append(dict(base, label="td1.1000", zeta=0.5, zeta_err=0.01, zeta_note=""))
    notes = format_table(rows).splitlines()[len(rows) + 1:]
    assert any("zeta_err not estimated: no variant of the fit window lies on the grid" in n
               and "(14 pulses)" in n for n in notes)
    assert any("zeta not fitted: edge-fit window is empty (td1.2000)" in n for n in notes)
    assert not any("td1.1000" in n for n in notes)
    assert any(n.startswith("no uncertainty in this table but zeta's") for n in notes)


def _all_helps():
    """(command path, help text, the parser's metavars) of every parser of the command line."""
    import argparse

    from slippulse.cli.app import build_parser

    def walk(p, path):
        metavars = {str(a.metavar or a.dest.upper()) for a in p._actions}
        yield " ".join(path), p.format_help(), metavars
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for name, sp in a.choices.items():
                    yield from walk(sp, path + [name])
    return list(walk(build_parser(), ["slippulse"]))


def test_help_texts_describe_things_not_source_files():
    """No help points at a source file or a module constant (`--cd-cs` named
    'steady/modeii.py CD_OVER_CS', `dynamic scan` 'Format: src/...scan.py')."""
    import re
    helps = _all_helps()
    assert len(helps) > 10
    bad = []
    for path, text, metavars in helps:
        flat = " ".join(text.split())
        bad += [(path, m) for m in re.findall(r"[\w./-]+\.py\b|\bsrc/", flat)]
        bad += [(path, m) for m in re.findall(r"\b[A-Z]+(?:_[A-Z]+)+\b", flat) if m not in metavars]
    assert not bad, bad


def test_cd_cs_help_states_the_default_values():
    import math
    import re

    from slippulse.cli.analyse import CD_CS_DEFAULTS
    from slippulse.steady.modeii import CD_OVER_CS
    stated = [math.sqrt(float(m[5:-1])) if m.startswith("sqrt") else float(m)
              for m in re.findall(r"sqrt\(\d+\)|\d+(?:\.\d+)?", CD_CS_DEFAULTS.split(",  ")[0]
                                  .split(" the ")[0])]
    assert stated == pytest.approx(list(CD_OVER_CS))
    for cd in CD_OVER_CS:                       # and the Poisson's ratios it quotes
        nu = (cd ** 2 - 2) / (2 * (cd ** 2 - 1))
        word = ("1/4" if abs(nu - 0.25) < 1e-12 else "1/3" if abs(nu - 1 / 3) < 1e-12
                else f"{nu:.2f}")
        assert word in CD_CS_DEFAULTS


def test_analysed_pulse_records_why_zeta_has_no_error(monkeypatch):
    """analyse_pulse names the missing part of zeta's error (here: no window variant fitted)."""
    import math

    import numpy as np

    from slippulse.steady import analysis
    real = analysis.edge_singularity

    def no_variants(*a, **k):
        es = dict(real(*a, **k))
        es.update(zeta_err_window=math.nan, zeta_err=math.nan)
        return es
    monkeypatch.setattr(analysis, "edge_singularity", no_variants)
    from test_figures import synthetic_pulse
    from slippulse.core.params import DEFAULT
    row = analysis.analyse_pulse(synthetic_pulse(1.05), DEFAULT)
    assert np.isfinite(row["zeta"]) and not np.isfinite(row["zeta_err"])
    assert "no variant of the fit window" in row["zeta_note"]
