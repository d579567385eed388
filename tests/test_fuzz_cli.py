"""Property-based fuzzing (Hypothesis) of the command line's argument validation and of the
readers of pulse, family and run files. Every input must end in a return code (0, 1, 2), an
argparse exit, or — for input that passes validation — at the stubbed work function; never in
another exception (which the console script would print as a traceback). A file made invalid
(a dangling or external link, NaN, a complex or non-positive slip rate, a 2-point grid, a label
that disagrees with its τ_d, β out of (0, 1), ``converged`` stored as a string, a broken
checkpoint) must be refused by every command that reads it: exit 2 with one line, never exit 0
and never the work. The work itself (solves, runs, spectra, figures) is replaced by a stub that
raises :class:`Reached`, so the default run stays in tens of seconds; ``-m slow`` runs the same
properties with a larger budget. (Seed files are written, never read, by the commands.)"""
import os
import shutil
import sys
import tempfile

import h5py
import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402

from slippulse.cli.app import main  # noqa: E402
from slippulse.core import h5io  # noqa: E402
from slippulse.core.params import DEFAULT as P  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_analysis import _synthetic_pulse  # noqa: E402

FUZZ = settings(max_examples=40, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])
#: The file properties: a small default budget; the slow variants run BIG examples.
SMALL = settings(FUZZ, max_examples=15)
BIG = settings(FUZZ, max_examples=200, derandomize=False)


class Reached(Exception):
    """The arguments passed validation and the command reached its work."""


def _reached(*args, **kwargs):
    raise Reached


@pytest.fixture(scope="module")
def files():
    d = tempfile.mkdtemp(prefix="fuzz-")
    good = os.path.join(d, "good.h5")
    for r, b, w in [(1.2, 0.02, 0.05), (1.1, 0.1, 0.1), (1.05, 0.3, 0.2)]:
        h5io.write_pulse(good, _synthetic_pulse(r, b, w), P)
    cfg = os.path.join(d, "run.toml")
    with open(cfg, "w") as fh:
        fh.write("[grid]\nn = 64\nlength = 0.5\n[time]\nmax_steps = 5\n")
    yield {"dir": d, "good": good, "cfg": cfg}
    shutil.rmtree(d, ignore_errors=True)


@pytest.fixture
def stubs(monkeypatch):
    import slippulse.cli.dynamic as cd
    import slippulse.cli.steady as cs
    import slippulse.dynamics.stepper as stepper
    import slippulse.plotting.steady as ps
    import slippulse.timedomain.seeding as seeding
    import slippulse.spectrum.family as spectrum
    import slippulse.timedomain.verify as verify
    import slippulse.steady.analysis as an
    import slippulse.steady.continuation as cont
    for mod, name in ((cs, "solve_any"), (cont, "run_family"), (verify, "verify_pulse"),
                      (seeding, "seed_pulse"), (stepper, "make_stepper"),
                      (spectrum, "run_spectrum"), (an, "analyse_family"), (ps, "load_family"),
                      (cd, "drive")):
        monkeypatch.setattr(mod, name, _reached)


def _outcome(argv):
    """'rc N', 'argparse', or 'reached'; any other exception fails the test (a traceback)."""
    try:
        rc = main(argv)
    except SystemExit as exc:
        assert exc.code in (0, 2), (argv, exc.code)
        return "argparse"
    except Reached:
        return "reached"
    assert rc in (0, 1, 2), (argv, rc)
    return f"rc {rc}"


NUMBERS = st.one_of(
    st.sampled_from(["inf", "-inf", "nan", "0", "-1", "1e-300", "1e300", "1e9", "-0", "1e-9",
                     "abc", "", " ", "1,5", "0x10", "1_000", "5e-3", "2", "16", "1.2", "1.02",
                     "1.3318", "1.33186", "1.0000001"]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(min_value=-10**20, max_value=10**20).map(str),
    st.text(max_size=8))

FLOAT_OPTIONS = {
    ("steady", "solve"): ["--tau-d", "--points", "--tol"],
    ("steady", "family"): ["--from", "--to", "--step", "--points", "--max-points", "--ds-min",
                           "--max-length"],
    ("dynamic", "verify"): ["--distance", "--points", "--dx", "--ahead", "--behind", "--xi-stab",
                            "--samples"],
    ("dynamic", "seed"): ["--dx", "--ahead", "--behind"],
}


@FUZZ
@given(cmd=st.sampled_from(sorted(FLOAT_OPTIONS)), data=st.data())
def test_fuzz_numeric_options(files, stubs, tmp_path, capsys, cmd, data):
    opts = data.draw(st.lists(st.sampled_from(FLOAT_OPTIONS[cmd]), min_size=1, max_size=3,
                              unique=True))
    argv = list(cmd)
    if cmd[0] == "dynamic":
        argv += ["--steady", files["good"], "--label", "td1.1000", "--no-progress"
                 ] if cmd[1] == "verify" else ["--steady", files["good"], "--label", "td1.1000"]
    argv += ["--out", str(tmp_path / "o.h5")]
    if cmd == ("steady", "solve"):
        argv += ["--no-figure", "-q"]
    if cmd == ("steady", "family"):
        argv += ["-q"]
    for opt in opts:
        argv += [f"{opt}={data.draw(NUMBERS)}"]
    res = _outcome(argv)
    err = capsys.readouterr().err
    assert "Traceback" not in err
    if res == "rc 2":
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[-1].startswith("slippulse: error: "), (argv, err)


SET_KEYS = ["fft.threads", "fft.planner", "grid.n", "grid.length", "time.t_end",
            "time.max_steps", "time.beta_cfl", "load.tau_d_ratio", "history.policy",
            "output.snapshot_every", "initial.kind", "nope.key", "grid", ""]
SET_VALUES = st.one_of(NUMBERS, st.sampled_from(["'estimate'", "'bogus'", "true", "[1, 2]",
                                                 "{a = 1}", "'soe'", "2048", "-3", "0"]))


@FUZZ
@given(pairs=st.lists(st.tuples(st.sampled_from(SET_KEYS), SET_VALUES), min_size=1, max_size=3))
def test_fuzz_dynamic_run_set(files, stubs, tmp_path, capsys, pairs):
    argv = ["dynamic", "run", files["cfg"], "--out", str(tmp_path / "run.h5"), "--overwrite",
            "--no-progress"]
    for k, v in pairs:
        argv += ["--set", f"{k}={v}"]
    _outcome(argv)
    assert "Traceback" not in capsys.readouterr().err


# ------------------------------------------------------------------ file readers

def _mutate(path, kind, data):
    """Apply one structured mutation to the pulse file at ``path``."""
    with h5py.File(path, "r+") as h5:
        grp = h5["pulses/td1.1000"]
        if kind == "drop_dataset":
            del grp[data.draw(st.sampled_from(sorted(h5io.DATASETS)))]
        elif kind == "drop_attr":
            del grp.attrs[data.draw(st.sampled_from(sorted(h5io.ATTRS)))]
        elif kind == "attr_type":
            name = data.draw(st.sampled_from(sorted(h5io.ATTRS)))
            grp.attrs[name] = data.draw(st.sampled_from(["text", np.array([1.0, 2.0]), -1,
                                                          np.nan, b"\xff"]))
        elif kind == "values":
            name = data.draw(st.sampled_from(sorted(h5io.DATASETS)))
            a = grp[name][...]
            a[data.draw(st.integers(0, a.size - 1))] = data.draw(
                st.sampled_from([np.nan, np.inf, -np.inf, 0.0, -1e300, 1e300]))
            grp[name][...] = a
        elif kind == "shape":
            name = data.draw(st.sampled_from(sorted(h5io.DATASETS)))
            a = grp[name][...]
            del grp[name]
            grp.create_dataset(name, data=a[: data.draw(st.integers(0, a.size - 1))])
        elif kind == "string_data":
            name = data.draw(st.sampled_from(sorted(h5io.DATASETS)))
            del grp[name]
            grp.create_dataset(name, data=np.array(["x"] * 4, dtype="S1"))
        elif kind == "label":
            h5.move("pulses/td1.1000", "pulses/" + data.draw(st.sampled_from(
                ["td", "tdnan", "tdinf", "td-1", "td1e300", "x", "td 1.1", "td1.1000.1"])))
        elif kind == "params":
            name = data.draw(st.sampled_from(sorted(h5io.PARAM_NAMES)))
            h5["parameters"].attrs[name] = data.draw(st.sampled_from([np.nan, -1.0, 0.0, "x"]))
        elif kind == "version":
            h5.attrs["format_version"] = data.draw(st.sampled_from([0, 3, -5, "two", 2.5]))
        elif kind == "converged":
            grp.attrs["converged"] = data.draw(st.sampled_from([False, "no", 0, np.array([1, 0])]))


def _readers(path, out_dir):
    """Every reader of pulse files: the library functions and the commands (work stubbed)."""
    for fn in (lambda: h5io.list_pulses(path), lambda: h5io.read_pulse(path, "td1.1000"),
               lambda: h5io.require_converged(path)):
        try:
            fn()
        except h5io.SchemaError:
            pass
    return [_outcome(argv) for argv in (
        ["dynamic", "seed", "--steady", path, "--label", "td1.1000", "--out",
         os.path.join(out_dir, "seed.h5")],
        ["dynamic", "verify", "--steady", path, "--label", "td1.1000", "--no-progress", "--out",
         os.path.join(out_dir, "v.h5")],
        ["steady", "stability", path, "--labels", "td1.1000"],
        ["steady", "analyse", path, "--no-write"],
        ["figures", path, "--outdir", os.path.join(out_dir, "figs")],
        ["steady", "solve", "--tau-d", "1.1", "--out", path, "--no-figure", "-q"],
    )]


KINDS = ["drop_dataset", "drop_attr", "attr_type", "values", "shape", "string_data", "label",
         "params", "version", "converged"]


@FUZZ
@given(kinds=st.lists(st.sampled_from(KINDS), min_size=1, max_size=2), data=st.data())
def test_fuzz_mutated_pulse_files(files, stubs, tmp_path, capsys, kinds, data):
    path = str(tmp_path / "m.h5")
    shutil.copyfile(files["good"], path)
    for kind in kinds:
        try:
            _mutate(path, kind, data)
        except (KeyError, ValueError, TypeError):
            pass                          # the mutation did not apply (an earlier one removed it)
    _readers(path, str(tmp_path))
    assert "Traceback" not in capsys.readouterr().err


@FUZZ
@given(cut=st.floats(0.0, 1.0), junk=st.binary(max_size=64), where=st.floats(0.0, 1.0))
def test_fuzz_truncated_and_garbled_files(files, stubs, tmp_path, capsys, cut, junk, where):
    raw = open(files["good"], "rb").read()
    n = int(cut * len(raw))
    at = int(where * n)
    path = str(tmp_path / "t.h5")
    with open(path, "wb") as fh:
        fh.write(raw[:at] + junk + raw[at + len(junk):n])
    _readers(path, str(tmp_path))
    assert "Traceback" not in capsys.readouterr().err


# ------------------------------------------------------------------ invalid files: always refused

def _invalidate(path, kind, data):
    """Make pulse td1.1000 of ``path`` invalid in one way (each ``kind`` always does)."""
    with h5py.File(path, "r+") as h5:
        pulses = h5["pulses"]
        grp = pulses["td1.1000"]
        name = data.draw(st.sampled_from(sorted(h5io.DATASETS)))
        if kind == "dangling_link":
            del pulses["td1.1000"]
            pulses["td1.1000"] = h5py.SoftLink("/nowhere")
        elif kind == "external_link":
            del pulses["td1.1000"]
            pulses["td1.1000"] = h5py.ExternalLink("other.h5", "/pulses/td1.1000")
        elif kind == "dangling_dataset":
            del grp[name]
            grp[name] = h5py.SoftLink("/nowhere")
        elif kind == "nan":
            a = grp[name][...]
            a[data.draw(st.integers(0, a.size - 1))] = data.draw(
                st.sampled_from([np.nan, np.inf, -np.inf]))
            grp[name][...] = a
        elif kind == "v_not_positive":
            a = grp["v"][...]
            a[data.draw(st.integers(0, a.size - 1))] = data.draw(st.sampled_from([0.0, -1e-9]))
            grp["v"][...] = a
        elif kind == "complex_v":
            a = grp["v"][...]
            del grp["v"]
            grp.create_dataset("v", data=a + 1j * a)
        elif kind == "two_points":
            for n in h5io.DATASETS:
                a = grp[n][...]
                del grp[n]
                grp.create_dataset(n, data=a[:2])
            grp.attrs["n_points"] = 2
        elif kind == "label_vs_attr":
            q = data.draw(st.sampled_from([1.2, 1.05, 1.1001]))
            grp.attrs["tau_d_ratio"] = q
            grp.attrs["tau_d"] = q * grp.attrs["tau_min"]
        elif kind == "tau_d_vs_ratio":
            grp.attrs["tau_d"] = 1.3 * grp.attrs["tau_min"]
        elif kind == "beta":
            grp.attrs["beta"] = data.draw(st.sampled_from([1.5, 1.0, 0.0, -0.1, np.nan]))
        elif kind == "length":
            grp.attrs["L"] = data.draw(st.sampled_from([np.nan, -1.0, 0.0, np.inf]))
        elif kind == "converged_text":
            grp.attrs["converged"] = data.draw(st.sampled_from(["False", "True", b"True"]))


INVALID = ["dangling_link", "external_link", "dangling_dataset", "nan", "v_not_positive",
           "complex_v", "two_points", "label_vs_attr", "tau_d_vs_ratio", "beta", "length",
           "converged_text"]


def _check_invalid_file(files, tmp_path, capsys, kind, data):
    path = str(tmp_path / "bad.h5")
    shutil.copyfile(files["good"], path)
    _invalidate(path, kind, data)
    with pytest.raises(h5io.SchemaError):
        h5io.read_pulse(path, "td1.1000")
    outcomes = _readers(path, str(tmp_path))
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert all(o == "rc 2" for o in outcomes), (kind, outcomes, err)
    lines = [ln for ln in err.splitlines() if ln.startswith("slippulse: error: ")]
    assert len(lines) == len(outcomes), err
    assert all(path in ln for ln in lines), (kind, err)       # each error names the file


@SMALL
@given(kind=st.sampled_from(INVALID), data=st.data())
def test_invalid_pulse_files_are_refused_by_every_reader(files, stubs, tmp_path, capsys, kind,
                                                         data):
    _check_invalid_file(files, tmp_path, capsys, kind, data)


@pytest.mark.slow
@BIG
@given(kind=st.sampled_from(INVALID), data=st.data())
def test_invalid_pulse_files_are_refused_by_every_reader_big(files, stubs, tmp_path, capsys,
                                                             kind, data):
    _check_invalid_file(files, tmp_path, capsys, kind, data)


# ------------------------------------------------------------------ run files (--resume)

@pytest.fixture(scope="module")
def run_file(files):
    out = os.path.join(files["dir"], "run.h5")
    assert main(["dynamic", "run", files["cfg"], "--out", out, "--no-progress"]) == 0
    return out


@pytest.fixture
def drive_stub(monkeypatch):
    import slippulse.cli.dynamic as cd
    monkeypatch.setattr(cd, "drive", _reached)


def _break_run(path, kind, data):
    """Make the run file invalid in one way (each ``kind`` always does)."""
    with h5py.File(path, "r+") as h5:
        ck = h5["checkpoint"]
        names = sorted(n for n, o in ck.items() if isinstance(o, h5py.Dataset)
                       and not o.is_scale and o.dtype.kind == "f" and o.size > 0)
        name = data.draw(st.sampled_from(names))
        if kind == "nan":
            a = np.array(ck[name][()], dtype=float)
            a.flat[data.draw(st.integers(0, a.size - 1))] = np.nan
            ck[name][()] = a
        elif kind == "dangling_link":
            del ck[name]
            ck[name] = h5py.SoftLink("/nowhere")
        elif kind == "external_link":
            del ck[name]
            ck[name] = h5py.ExternalLink("other.h5", "/x")
        elif kind == "no_checkpoint":
            del h5["checkpoint"]
        elif kind == "config":
            h5["config"].attrs["json"] = data.draw(st.sampled_from(["{", "[]", "3", '{"a": 1}']))
        elif kind == "no_config":
            del h5["config"]
        elif kind == "kind":
            h5.attrs["kind"] = data.draw(st.sampled_from(["steady", "", "dynamic2"]))
        elif kind == "version":
            h5.attrs["format_version"] = data.draw(st.sampled_from([0, 3, "two"]))


RUN_INVALID = ["nan", "dangling_link", "external_link", "no_checkpoint", "config", "no_config",
               "kind", "version"]


def _check_invalid_run(files, run_file, tmp_path, capsys, kind, data):
    path = str(tmp_path / "run.h5")
    shutil.copyfile(run_file, path)
    _break_run(path, kind, data)
    before = open(path, "rb").read()
    res = _outcome(["dynamic", "run", files["cfg"], "--out", path, "--resume", "--no-progress"])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert res == "rc 2", (kind, res, err)
    assert len([ln for ln in err.splitlines() if ln.strip()]) == 1, err
    assert open(path, "rb").read() == before                  # a refused resume changes nothing
    assert not os.path.exists(path + ".partial")


def test_a_valid_run_file_resumes(files, run_file, drive_stub, tmp_path):
    path = str(tmp_path / "run.h5")
    shutil.copyfile(run_file, path)
    assert _outcome(["dynamic", "run", files["cfg"], "--out", path, "--resume",
                     "--no-progress"]) == "reached"


@SMALL
@given(kind=st.sampled_from(RUN_INVALID), data=st.data())
def test_invalid_run_files_are_refused_by_resume(files, run_file, drive_stub, tmp_path, capsys,
                                                 kind, data):
    _check_invalid_run(files, run_file, tmp_path, capsys, kind, data)


@pytest.mark.slow
@BIG
@given(kind=st.sampled_from(RUN_INVALID), data=st.data())
def test_invalid_run_files_are_refused_by_resume_big(files, run_file, drive_stub, tmp_path,
                                                     capsys, kind, data):
    _check_invalid_run(files, run_file, tmp_path, capsys, kind, data)
