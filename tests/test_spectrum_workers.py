"""The spectrum command on several workers (`slippulse steady stability --workers K`, on Dask),
and the search below MIN_RE by the sign of det M (`spectrum.pulse.scan_below`)."""
from dataclasses import replace

import numpy as np
import pytest

from slippulse.spectrum.eigensolve import newton_eigen
from slippulse.spectrum.pulse import MIN_RE, SCAN_LO, scan_below
from slippulse.spectrum.family import NO_TRACKING, Run, Tracking, split_runs


class _DiagonalOp:
    """M(σ) = A − σ I with A symmetric, eigenvalues `eigs` (1/s), rate unit 1: a nonlinear
    eigenproblem whose answer is known."""

    def __init__(self, eigs, seed=3):
        rng = np.random.default_rng(seed)
        q, _ = np.linalg.qr(rng.standard_normal((len(eigs), len(eigs))))
        self.A = q @ np.diag(eigs) @ q.T
        self.q = q
        self.n = len(eigs)
        self.rate_unit = 1.0
        self.det_calls = 0

    def matrices(self, sigma, deriv=True):
        if not deriv:
            self.det_calls += 1
        M = self.A - sigma * np.eye(self.n)
        return (M.astype(complex) if deriv else M), (-np.eye(self.n) if deriv else None)


def _collector(op):
    found = []

    def add(sig, vec, floor):
        if not sig.real > floor * op.rate_unit:
            return False
        eig = newton_eigen(op, sig, vec, tol=1e-10, min_re=floor * op.rate_unit)
        if eig.converged:
            found.append(eig.sigma)
            return True
        return False
    return add, found


@pytest.mark.parametrize("s0", [3.3e-4, 7.0e-5, 2.0e-6])
def test_scan_below_finds_a_small_real_eigenvalue(s0):
    # translation at 0 (pinned), the rest stable: only s0 lies in (0, MIN_RE)
    eigs = [0.0, s0] + list(-np.linspace(0.01, 3.0, 28))
    op = _DiagonalOp(eigs)
    add, found = _collector(op)
    scan_below(op, add)
    assert len(found) == 1
    assert found[0].real == pytest.approx(s0, rel=1e-8)
    assert abs(found[0].imag) < 1e-12


def test_scan_below_walks_down_and_stops_at_the_first_bracket():
    op = _DiagonalOp([0.0, 2e-4, 3e-6] + list(-np.linspace(0.01, 3.0, 27)))
    add, found = _collector(op)
    scan_below(op, add)
    assert [round(f.real, 12) for f in found] == [2e-4]        # the largest one, alone
    assert op.det_calls <= 4                                  # 1e-3, 3.2e-4, 1e-4: stop


def test_scan_below_finds_nothing_in_a_stable_spectrum():
    op = _DiagonalOp([0.0] + list(-np.linspace(0.01, 3.0, 29)))
    add, found = _collector(op)
    scan_below(op, add)
    assert found == []
    assert SCAN_LO < MIN_RE


def test_runs_are_cut_at_kept_spectra_and_halved_for_the_workers():
    """Runs are contiguous pulses to compute; a kept spectrum ends a run and seeds the next one;
    the longest run is halved until there are enough for the workers, the lower half from the
    default search."""
    kept = {"sigma": np.array([0.5 + 0j]), "rate_unit_c_over_L": 2.0, "V": np.zeros((0, 3)),
            "xi": np.zeros(3), "L": 1.0}
    plan = [(f"p{k}", kept if k == 3 else None) for k in range(10)]
    seed = Tracking.from_guess(7.0)
    runs = split_runs(plan, seed, 1)
    assert [r.labels for r in runs] == [["p0", "p1", "p2"], [f"p{k}" for k in range(4, 10)]]
    assert runs[0].seed is seed and runs[1].seed.sigmas[0] == 0.5
    runs = split_runs(plan, seed, 3)
    assert [r.labels for r in runs] == [["p0", "p1", "p2"], ["p4", "p5", "p6"],
                                        ["p7", "p8", "p9"]]
    assert runs[2].seed is NO_TRACKING
    assert sum((r.labels for r in split_runs(plan, seed, 40)), []) == \
        [lab for lab, k in plan if k is None]


def test_two_workers_claim_a_run_from_both_ends_once_each():
    """Two workers on one run: one from the top, one from the bottom, each pulse exactly once,
    in their own directions, whatever the interleaving; they stop where they meet."""
    rng = np.random.default_rng(4)
    for n in (1, 2, 7, 40):
        run = Run([f"p{k:02d}" for k in range(n)])
        got = {1: [], -1: []}
        while True:
            step = int(rng.choice([1, -1]))
            lab = run.claim(step)
            if lab is None:
                assert run.claim(-step) is None
                break
            got[step].append(lab)
        assert sorted(got[1] + got[-1]) == run.labels
        assert got[1] == sorted(got[1]) and got[-1] == sorted(got[-1], reverse=True)
        if got[1] and got[-1]:
            assert max(got[1]) < min(got[-1])


def _two_pulse_file(tmp_path, pulse12, params):
    from slippulse.core.h5io import write_pulse
    f = str(tmp_path / "fam.h5")
    base = pulse12.to_pulse()
    for q in (1.2, 1.19, 1.18):
        write_pulse(f, replace(base, tau_d_ratio=q, tau_d=q * base.tau_min), params)
    return f


def test_the_family_spectrum_on_a_dask_cluster_stores_the_serial_values(tmp_path, pulse12,
                                                                        params):
    """The same three pulses serially and on a dask.distributed LocalCluster of two workers
    (threads of this process, to keep the test cheap; the path through Client.submit and
    as_completed is the one a process cluster or a remote scheduler takes): the stored
    eigenvalues agree within Newton's tolerance, every pulse once, and each result records its
    settings and its level-0 attempt. With two workers the bottom pulse starts from the default
    search, not from its neighbour."""
    import shutil

    from distributed import Client, LocalCluster

    from slippulse.core.executor import ExecutorSettings
    from slippulse.spectrum.pulse import read_spectrum
    from slippulse.spectrum.family import SpectrumSettings, run_spectrum
    f = _two_pulse_file(tmp_path, pulse12, params)
    g = str(tmp_path / "dask.h5")
    shutil.copy(f, g)
    s = SpectrumSettings(levels=0, min_points=0, extra=False, pin_translation=False)
    serial = run_spectrum(f, s)
    seen = []
    par = run_spectrum(g, s, progress=lambda lab, res, st: seen.append(lab),
                       executor=ExecutorSettings(workers=2, processes=False))
    assert sorted(seen) == ["td1.1800", "td1.1900", "td1.2000"]
    assert not serial.failed and not par.failed
    for lab in seen:
        a, b = read_spectrum(f, lab), read_spectrum(g, lab)
        assert a["status"] == b["status"] == "converged"
        assert complex(b["sigma"][0]) == pytest.approx(complex(a["sigma"][0]), rel=1e-9)
        assert b["settings"] == str(s) and b["level0_attempt"] == "the pulse's own grid"
        assert all(b[k] == a[k] for k in a if k.startswith("setting_"))
    # an open client (a remote scheduler's, here a local one) is used as given
    with LocalCluster(n_workers=2, processes=False, dashboard_address=None) as cl, \
            Client(cl) as client:
        from slippulse.core.executor import TaskPool
        with TaskPool(client=client) as pool:
            assert pool.parallel and pool.n_workers == 2
            out = pool.map(abs, [-1, -2, 3])
        assert out == {-1: 1, -2: 2, 3: 3}


def test_an_interrupted_cluster_run_resumes_from_what_was_written(tmp_path, pulse12, params):
    """Interrupted after its first result (Ctrl-C or SIGTERM reach the command as
    KeyboardInterrupt), a run on a Dask cluster stops and closes it; the result written so far
    stays, and the rerun keeps it and computes only the others."""
    from slippulse.core.executor import ExecutorSettings
    from slippulse.spectrum.family import SpectrumSettings, run_spectrum
    from slippulse.spectrum.pulse import read_spectrum
    f = _two_pulse_file(tmp_path, pulse12, params)
    s = SpectrumSettings(levels=0, min_points=0, extra=False, pin_translation=False)
    ex = ExecutorSettings(workers=2, processes=False)
    done = []

    def stop_after_one(lab, res, stored):
        done.append(lab)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_spectrum(f, s, executor=ex, progress=stop_after_one)
    written = [lab for lab in ("td1.2000", "td1.1900", "td1.1800")
               if read_spectrum(f, lab) is not None]
    assert written == done
    again = run_spectrum(f, s, executor=ex)
    assert again.skipped == done and len(again.results) == 2 and not again.failed


def test_cli_refuses_bad_worker_counts(tmp_path, pulse12, params):
    import cli_inproc

    from slippulse.core.h5io import write_pulse
    good = tmp_path / "one.h5"
    write_pulse(str(good), pulse12.to_pulse(), params)
    cases = [(["--workers", "0"], "workers=0 is invalid"),
             (["--threads", "0"], "threads=0 is invalid"),
             (["--scheduler", " "], "--scheduler=' ' is invalid")]
    for args, msg in cases:
        r = cli_inproc.run(["steady", "stability", good, "-q", *args])
        assert r.returncode == 2, (args, r.stderr)
        assert msg in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_newton_onto_a_real_eigenvalue_never_carries_a_subnormal_imaginary_part():
    """Quadratic convergence squares Im σ at each step (1e-17, 1e-34, ... 1e-318): a subnormal
    imaginary part then slowed every kernel assembly 20×. Iterates of Newton onto a
    real eigenvalue, started from a guess with a subnormal imaginary part, are exactly real."""
    from slippulse.spectrum.eigensolve import snap_real
    op = _DiagonalOp([0.0, 0.37] + list(-np.linspace(0.01, 3.0, 28)))
    rng = np.random.default_rng(5)
    x0 = op.q[:, 1] + 0.05 * (rng.standard_normal(op.n) + 1j * rng.standard_normal(op.n))
    eig = newton_eigen(op, complex(0.30, 1.1e-318), x0, tol=1e-12, min_re=1e-3)
    assert eig.converged and eig.sigma.real == pytest.approx(0.37, rel=1e-12)
    assert eig.sigma.imag == 0.0
    assert all(h.imag == 0.0 or abs(h.imag) > 1e-250 for h in eig.history)
    # a complex eigenvalue keeps its imaginary part, however small against 1e-13 it is not
    assert snap_real(1.0 + 1e-9j, 1.0) == 1.0 + 1e-9j
    assert snap_real(1.0 + 1e-300j, 1.0).imag == 0.0
