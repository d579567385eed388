"""`slippulse steady fold-ratio`: the rates of record against the family's slope; bad input."""
import numpy as np

from slippulse.cli.app import main
from slippulse.spectrum.records import read_rates, records_fold_ratio

SEEDS = ["steady/seeds/seed_2550m.h5", "steady/seeds/seed_4892m.h5", "steady/seeds/seed_6594m.h5",
         "steady/seeds/seed_9473m.h5", "steady/seeds/seed_10111m.h5"]
RECORDS = "docs/results/records.toml"


def test_ratio_is_rate_over_slope():
    rates = read_rates(RECORDS)
    assert np.all(np.diff(rates["L"]) >= 0) and np.all(rates["s_err"] > 0)
    fr = records_fold_ratio(rates, SEEDS)
    ok = np.isfinite(fr["R"])
    assert ok.sum() >= 10
    assert np.allclose(fr["R"][ok], fr["s"][ok] / np.abs(fr["slope"][ok]))
    # the family's τ_d falls as L grows: a negative slope wherever it is known
    assert np.all(fr["slope"][ok] < 0)


def test_cli_summary_and_bad_input(tmp_path, capsys):
    assert main(["steady", "fold-ratio", *SEEDS, "--records", RECORDS, "--from-length", "100"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert "R ∝ L^(" in last and "±" in last
    (tmp_path / "r.toml").write_text("[other]\nx = 1\n")
    for argv, word in ((["--records", str(tmp_path / "r.toml")], "--records"),
                       (["--records", "nowhere.toml"], "--records"),
                       (["--from-length", "1e9"], "--from-length"),
                       (["--from-length", "nan"], "--from-length")):
        assert main(["steady", "fold-ratio", SEEDS[0], *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and word in err[0]
