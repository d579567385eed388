"""`slippulse steady long-domain`: a pulse re-solved on a longer domain is the same pulse (paper
Fig. S1b); bad input exits 2."""
import pytest

from slippulse.cli.app import main
from slippulse.core.h5io import read_pulse


def test_longer_domain_gives_the_same_pulse(tmp_path, capsys):
    fam = str(tmp_path / "f.h5")
    assert main(["steady", "solve", "--tau-d", "1.2", "--points", "500", "--out", fam]) == 0
    out = str(tmp_path / "long.h5")
    assert main(["steady", "long-domain", fam, "--label", "td1.2000", "--factor", "8",
                 "--out", out]) == 0
    short, long = read_pulse(fam)[0], read_pulse(out)[0]
    assert long.converged and long.extra["domain_factor"] == 8.0
    assert long.xi[-1] - long.xi[0] > 7.0 * (short.xi[-1] - short.xi[0])
    assert long.L == pytest.approx(short.L, rel=1e-3)
    assert long.beta == pytest.approx(short.beta, rel=1e-3)
    capsys.readouterr()
    for argv, word in ((["--label", "td9.9"], "--label"), (["--factor", "0.5"], "--factor")):
        assert main(["steady", "long-domain", fam, *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and word in err[0]
