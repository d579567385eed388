"""Parameters as input of every command: --params FILE.toml and --set params.NAME=VALUE,
one resolver (core.params.resolve_params) with name/range/N-shape checks, parameters taken from
the files a command reads, and mixing of parameters refused with the differing name."""
import dataclasses as dc

import h5py
import pytest

from slippulse.cli.app import build_parser, main
from slippulse.core.h5io import read_pulse, write_pulse
from slippulse.core.params import (DEFAULT, ParameterError, differing, explicit_params,
                                   resolve_params)

COMMANDS = [["steady", "solve"], ["steady", "family"], ["steady", "stability", "F"],
            ["steady", "analyse", "F"], ["figures", "F"], ["dynamic", "seed", "--steady", "F"],
            ["dynamic", "verify", "--steady", "F"], ["dynamic", "scan", "S.toml"]]


def _line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("slippulse: error:"), err
    return err[0]


@pytest.fixture(scope="module")
def steady_file(tmp_path_factory, pulse12):
    path = str(tmp_path_factory.mktemp("p") / "td.h5")
    write_pulse(path, pulse12.to_pulse(), DEFAULT)
    return path


def test_resolver_order_and_values(tmp_path):
    f = tmp_path / "p.toml"
    f.write_text("[params]\nsigma = 2e6\nb = 0.08\n[grid]\nn = 8\n")   # other tables ignored
    p = resolve_params(str(f), ["params.b=0.09"])
    assert (p.sigma, p.b, p.mu) == (2e6, 0.09, DEFAULT.mu)         # file, then --set, else Table I
    assert explicit_params(str(f)) == {"sigma": 2e6, "b": 0.08}
    assert differing(p, DEFAULT) == ["sigma", "b"]
    assert resolve_params() == DEFAULT


@pytest.mark.parametrize("item, words", [
    ("params.foo=1", ["unknown parameter 'foo'", "known: mu"]),
    ("params.b=abc", ["b='abc'", "in (0, 10)"]),
    ("params.mu=0", ["mu=0.0", "> 0 Pa"]),
    ("params.D=-1e-6", ["D=-1e-06", "> 0 m"]),
    ("params.c_s=nan", ["c_s=nan", "finite"]),
    ("params.sigma=inf", ["sigma=inf", "finite"]),
    ("params.b=20", ["b=20.0", "in (0, 10)"]),
    ("params.alpha=1e-9", ["no minimum", "a law without a minimum has no steady pulse"]),
    ("params.alpha=0.03", ["f0*b", "must exceed alpha"]),
    ("sigma=2", ["params.NAME=VALUE"]),
])
def test_bad_values_refused(item, words, capsys, tmp_path):
    with pytest.raises(ParameterError) as exc:
        resolve_params(sets=[item])
    for w in words:
        assert w in str(exc.value)
    out = tmp_path / "x.h5"
    assert main(["steady", "solve", "--out", str(out), "--set", item, "-q"]) == 2
    assert not out.exists() and not (tmp_path / "x.png").exists()
    assert words[0] in _line(capsys)


def test_bad_params_file(tmp_path, capsys):
    f = tmp_path / "p.toml"
    f.write_text("[grid]\nn = 8\n")
    assert main(["steady", "solve", "--params", str(f), "--out", str(tmp_path / "x.h5")]) == 2
    assert "no [params] table" in _line(capsys)
    f.write_text("[params]\nsigmaa = 1e6\n")
    assert main(["steady", "family", "--params", str(f), "--out", str(tmp_path / "x.h5")]) == 2
    assert "unknown parameter 'sigmaa'" in _line(capsys)
    f.write_text("[params\n")
    assert main(["steady", "solve", "--params", str(f), "--out", str(tmp_path / "x.h5")]) == 2
    assert "not valid TOML" in _line(capsys)


@pytest.mark.parametrize("argv", COMMANDS, ids=lambda a: " ".join(a[:2]))
def test_every_command_takes_params_and_set(argv):
    args = build_parser().parse_args(argv + ["--params", "q.toml", "--set", "params.b=0.08"])
    assert args.params == "q.toml"
    assert getattr(args, "param_sets") == ["params.b=0.08"]


def test_dynamic_run_takes_params(tmp_path):
    args = build_parser().parse_args(["dynamic", "run", "c.toml", "--params", "q.toml",
                                      "--set", "params.b=0.08"])
    assert args.params == "q.toml" and args.sets == ["params.b=0.08"]


@pytest.mark.parametrize("argv", [
    ["steady", "stability", "{f}"], ["steady", "analyse", "{f}", "--no-write"],
    ["figures", "{f}", "--outdir", "{d}"], ["dynamic", "seed", "--steady", "{f}", "--out", "{o}"],
    ["dynamic", "verify", "--steady", "{f}", "--out", "{o}", "--distance", "0.01"]],
    ids=lambda a: " ".join(a[:2]))
def test_readers_refuse_other_params(argv, steady_file, tmp_path, capsys):
    """A command that reads a file takes its parameters; a different given value is refused,
    naming the parameter, before any work and without writing."""
    with h5py.File(steady_file) as h5:
        before = dict(h5["pulses"]["td1.2000"].attrs)
    fill = dict(f=steady_file, d=str(tmp_path / "figs"), o=str(tmp_path / "o.h5"))
    av = [a.format(**fill) for a in argv]
    assert main(av + ["--set", "params.sigma=2e6"]) == 2
    line = _line(capsys)
    assert "sigma=1000000 (in the file) vs 2000000 (given)" in line
    assert not (tmp_path / "o.h5").exists() and not (tmp_path / "figs").exists()
    with h5py.File(steady_file) as h5:
        assert dict(h5["pulses"]["td1.2000"].attrs).keys() == before.keys()


def test_reader_accepts_agreeing_params(steady_file, tmp_path, capsys):
    f = tmp_path / "p.toml"
    f.write_text("[params]\nsigma = 1e6\nmu = 9e9\n")
    assert main(["steady", "analyse", steady_file, "--no-write", "--params", str(f)]) == 0


def test_scan_refuses_other_params(steady_file, tmp_path, capsys):
    scan = tmp_path / "s.toml"
    scan.write_text(f'[scan]\nname = "t"\nout_dir = "{tmp_path / "out"}"\n'
                    f'[defaults]\nsteady = "{steady_file}"\n[grid]\nlabel = ["td1.2000"]\n')
    assert main(["dynamic", "scan", str(scan), "--set", "params.alpha=0.006", "--dry-run"]) == 2
    assert "alpha=0.005 (in the file) vs 0.006 (given)" in _line(capsys)


def test_writers_refuse_mixing(steady_file, tmp_path, capsys):
    """A pulse or a family of other parameters is not added to a file (checked before solving)."""
    for cmd in (["steady", "solve", "--tau-d", "1.1"], ["steady", "family"]):
        assert main(cmd + ["--out", steady_file, "--set", "params.D=6e-7", "-q"]) == 2
        assert "D=5e-07 (in the file) vs 6e-07 (given)" in _line(capsys)
    assert read_pulse(steady_file)[1] == DEFAULT


def test_mode_ii_ratio_is_a_parameter(steady_file, capsys):
    assert main(["steady", "analyse", steady_file, "--no-write", "--cd-cs", "1.0"]) == 2
    assert "cd-cs=1.0" in _line(capsys)
    assert main(["steady", "analyse", steady_file, "--no-write", "--cd-cs", "2.0"]) == 0


def test_solve_stores_given_params(tmp_path, capsys):
    """(μ, σ) → 3.7 (μ, σ) from the command line: stored in the file, and the same β (exact
    similarity) as Table I."""
    k = 3.7
    out = str(tmp_path / "s.h5")
    assert main(["steady", "solve", "--points", "500", "--out", out, "--no-figure", "-q",
                 "--set", f"params.mu={k * 9e9!r}", "--set", f"params.sigma={k * 1e6!r}"]) == 0
    pulse, params = read_pulse(out)
    assert params == dc.replace(DEFAULT, mu=k * 9e9, sigma=k * 1e6)
    with h5py.File(out) as h5:
        assert h5["parameters"].attrs["sigma"] == k * 1e6
        assert h5["parameters"].attrs["sigma_units"] == "Pa"
    assert abs(pulse.tau_min / DEFAULT.tau_min - k) < 1e-12


def test_dynamic_run_params_file_into_config(tmp_path, capsys):
    """dynamic run: config file → --params → --set; the resolved parameters are stored."""
    cfg = tmp_path / "run.toml"
    cfg.write_text("[grid]\nn = 64\nlength = 0.5\n[params]\nsigma = 3e6\n"
                   "[time]\nstepping = \"adaptive\"\nmax_steps = 3\n")
    prm = tmp_path / "p.toml"
    prm.write_text("[params]\nsigma = 2e6\nb = 0.08\n")
    out = str(tmp_path / "r.h5")
    assert main(["dynamic", "run", str(cfg), "--params", str(prm), "--set", "params.b=0.07",
                 "--out", out, "--no-progress"]) == 0
    with h5py.File(out) as h5:
        assert h5["parameters"].attrs["sigma"] == 2e6 and h5["parameters"].attrs["b"] == 0.07
    capsys.readouterr()
    bad = str(tmp_path / "bad.h5")
    assert main(["dynamic", "run", str(cfg), "--set", "params.alpha=1e-9", "--out", bad,
                 "--no-progress"]) == 2
    assert "without a minimum" in _line(capsys)
    import os
    assert not os.path.exists(bad)


def test_verify_attributes_drift_to_the_pulses_eigenvalue_for_any_params():
    """The drift is attributed to the pulse's own eigenvalue, not to a table of Table-I rates: a
    pulse of other parameters (table_I False) gets its drift attributed to its eigenvalue; none without one."""
    import numpy as np

    from slippulse.timedomain.verify import VerifyResult, drift_verdict, mode_growth
    info = {"tau_d_ratio": 1.2, "growth_rate_v_max": 48.5, "travelled": 0.3,
            "status": "finished", "table_I": False}
    res = VerifyResult(t=np.zeros(5), x_front=np.zeros(5), series={}, errors={}, info=info)
    verdict, text = drift_verdict(res)
    assert mode_growth(info) is None and verdict is None and "no eigenvalue" in text
    eig = {**info, "eigen_s_per_L": 48.98, "eigen_translation_s_per_L": 1e-4,
           "eigen_source": "stored"}
    assert mode_growth(eig)[0] == 48.98
    assert drift_verdict(dc.replace(res, info=eig))[0] is True


@pytest.mark.slow
def test_homotopy_solves_rock_set(tmp_path, capsys):
    """steady/rock.toml: the built-in guess does not reach it (docs/results.md §1); --homotopy
    does, and the file carries the rock parameters."""
    import os
    rock = os.path.join(os.path.dirname(__file__), os.pardir, "steady", "rock.toml")
    out = str(tmp_path / "r.h5")
    assert main(["steady", "solve", "--params", rock, "--homotopy", "--points", "500", "--out", out,
                 "--no-figure", "-q"]) == 0
    pulse, params = read_pulse(out)
    assert pulse.converged and params == resolve_params(rock)
    assert abs(pulse.beta - 7.34e-4) < 1e-5


def test_figures_carry_params(pulse12, tmp_path):
    """The quick-look PNG of a solve holds its parameters (PNG text chunk, JSON)."""
    import json

    from PIL import Image

    from slippulse.plotting.quicklook import plot_pulse
    path = str(tmp_path / "q.png")
    plot_pulse(pulse12.to_pulse(), DEFAULT, path)
    text = Image.open(path).text["Description"]
    assert json.loads(text.split(": ", 1)[1]) == DEFAULT.as_dict()
