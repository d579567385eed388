"""`slippulse steady referee`: the slip criterion on committed pulses, and bad input."""
import pytest

from slippulse.cli.app import main

SEEDS = ["steady/seeds/seed_2550m.h5", "steady/seeds/seed_4892m.h5"]


def test_slip_criterion_on_the_seeds(capsys):
    """The deep pulses of the seeds: total slip falls as τ_d rises (db/dq < 0), the criterion's
    'unstable', at every pulse with a derivative; no Eqs. 3-4 fit (no pulse in the paper's
    range), said in words."""
    assert main(["steady", "referee", *SEEDS]) == 0
    out = capsys.readouterr().out
    rows = [ln.split() for ln in out.splitlines() if ln.startswith("td1.")]
    assert len(rows) == 4 and all(float(r[5]) < 0 and r[6] == "unstable" for r in rows)
    assert "window (1.015, 1.2): no fit" in out
    assert "db/dq < 0 at 4 of 4" in out.splitlines()[-1]


@pytest.mark.parametrize("argv, word", [
    (["--records", "nowhere.toml"], "--records"),
    (["--records", "pyproject.toml"], "--records"),
])
def test_bad_records_exit_2(capsys, argv, word):
    assert main(["steady", "referee", SEEDS[0], *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and word in err[0]
