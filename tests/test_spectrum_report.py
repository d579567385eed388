"""The spectrum tables and the power law near τ_min (spectrum/report.py), the SBI rates file
(timedomain/sbi_rates.py) and ``slippulse dynamic spectrum-report``'s refusals."""
import math

import numpy as np
import pytest

from cli_inproc import run as cli
from slippulse.spectrum.report import near_min_fits, refined_rows, spectrum_rows
from slippulse.timedomain.sbi_rates import read_sbi_rates


def _spectrum(q, s_per_L, unit=50.0, refined=None):
    """A stored-spectrum dict as family_spectra returns it: leading σ = s_per_L·unit (1/s)."""
    o = {"label": f"td{q:.4f}", "tau_d_ratio": q, "c_p": 0.3 * 2739.0, "L": 2.0,
         "rate_unit_c_over_L": unit, "sigma": np.array([complex(s_per_L * unit, 0.5 * unit)]),
         "n_unstable": 1, "translation_s_per_L": 1e-6}
    if refined is not None:
        s, err = refined
        o.update({"s_per_L": s, "s_err_per_L": err, "refine_n_points": np.array([2000, 2828]),
                  "refine_s_levels": np.array([s + err, s]) * unit,
                  "refine_translation_levels": np.array([2e-6, 1e-6]) * unit})
    return o


def test_rows_are_per_pulse_length_and_refined_rows_only_where_refined():
    sp = [_spectrum(1.1, 8.0, refined=(7.9, 0.01)), _spectrum(1.05, 0.6),
          dict(_spectrum(1.2, 0.0), sigma=np.array([], complex))]
    rows = spectrum_rows(sp, c_s=2739.0)
    assert rows[0]["s_per_L"] == pytest.approx(8.0) and rows[0]["s"] == pytest.approx(400.0)
    assert rows[0]["im_per_L"] == pytest.approx(0.5) and rows[0]["beta"] == pytest.approx(0.3)
    assert math.isnan(rows[2]["s_per_L"])                   # no eigenvalue stored
    ref = refined_rows(sp)
    assert [r["label"] for r in ref] == ["td1.1000"]
    assert ref[0]["s_levels"] == pytest.approx([7.91, 7.9]) and ref[0]["levels"] == [2000, 2828]
    assert ref[0]["s"] == pytest.approx(7.9 * 50.0)


def test_power_law_near_tau_min_is_recovered_on_the_resolved_rates_of_each_window():
    """s L/c_p = 2 (q − 1)^1.5 exactly at 7 pulses in (1.01, 1.05), plus one unresolved pulse
    (s < 2 s_err) far off the law: every window recovers A and n, and no fit takes the
    unresolved pulse; a window with fewer than 3 pulses gives no fit."""
    qs = np.array([1.01, 1.015, 1.02, 1.025, 1.03, 1.04, 1.05])
    refined = [dict(tau_d_ratio=q, s_per_L=2 * (q - 1) ** 1.5, s_err_per_L=1e-4 * 2 * (q - 1) ** 1.5)
               for q in qs]
    refined.append(dict(tau_d_ratio=1.012, s_per_L=1.0, s_err_per_L=0.6))   # sign unresolved
    fits = near_min_fits(refined, windows=((1.0, 1.051), (1.019, 1.051), (1.045, 1.051)))
    assert [f["window"] for f in fits] == [(1.0, 1.051), (1.019, 1.051)]
    for f in fits:
        assert f["law"].n == pytest.approx(1.5, abs=1e-9)
        assert f["law"].A == pytest.approx(2.0, rel=1e-9)
        assert np.all(np.abs(f["pulls"]) < 1e-6)
    assert fits[0]["law"].m == 7 and fits[1]["law"].m == 5


def test_the_committed_rates_file_reads_and_a_file_without_provenance_is_refused(tmp_path):
    rates = read_sbi_rates("dynamic/results/sbi_growth_rates.toml")
    assert rates and all(set(r) == {"tau_d_ratio", "s", "err", "domain"} for r in rates)
    assert all(r["err"] > 0 for r in rates)
    bare = tmp_path / "r.toml"
    bare.write_text("[[rates]]\ntau_d_ratio = 1.2\ns = 1.0\nerr = 0.1\ndomain = 'x'\n")
    with pytest.raises(ValueError, match="source"):
        read_sbi_rates(str(bare))
    bad = tmp_path / "b.toml"
    bad.write_text("[source]\nkind = 'run'\n[[rates]]\ntau_d_ratio = 1.2\ns = 1.0\n")
    with pytest.raises(ValueError, match="'err'"):
        read_sbi_rates(str(bad))


@pytest.mark.parametrize("argv, word", [
    (["{tmp}/no.h5"], "FAMILY"),
    (["{st}", "--sbi-rates", "{tmp}/no.toml"], "--sbi-rates"),
    (["{st}", "--sbi-rates", "{tmp}/bare.toml"], "--sbi-rates"),
    (["{st}", "--figdir", "{tmp}/afile"], "--figdir"),
    (["{tmp}/empty.h5"], "no converged spectrum"),
])
def test_bad_input_is_one_line_exit_2(tmp_path, steady12_with_spectrum, pulse12, params, argv,
                                      word):
    from slippulse.core.h5io import write_pulse
    (tmp_path / "bare.toml").write_text("[[rates]]\n")
    (tmp_path / "afile").write_text("")
    write_pulse(str(tmp_path / "empty.h5"), pulse12.to_pulse(), params)    # no spectrum stored
    args = [a.format(tmp=tmp_path, st=steady12_with_spectrum) for a in argv]
    r = cli(["dynamic", "spectrum-report", *args, *(["--figdir", tmp_path / "f"]
                                                  if "--figdir" not in args else [])])
    assert r.returncode == 2, r.stdout + r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and word in r.stderr
