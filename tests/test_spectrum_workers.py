"""The spectrum command on several worker processes, and the search below MIN_RE by the sign of
det M (stop 37: `slippulse steady stability --workers K`, `spectrum.scan_below`)."""
from dataclasses import replace

import numpy as np
import pytest

from slippulse.spectrum.eigensolve import newton_eigen
from slippulse.spectrum.pulse import MIN_RE, SCAN_LO, scan_below
from slippulse.spectrum.family import split_chunks


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


def test_split_chunks_are_contiguous_and_cover_every_label():
    labels = [f"p{k}" for k in range(11)]
    chunks = split_chunks(labels, 4)
    assert sum(chunks, []) == labels
    assert len(chunks) == 4 and max(map(len, chunks)) - min(map(len, chunks)) <= 1
    assert split_chunks(labels[:2], 5) == [["p0"], ["p1"]]


def test_two_workers_claim_a_run_from_both_ends_once_each():
    """Two workers on one run: one from the top, one from the bottom, each index exactly once,
    in their own directions, whatever the interleaving; they stop where they meet."""
    from slippulse.spectrum.family import claim
    rng = np.random.default_rng(4)
    for n in (1, 2, 7, 40):
        counter = [0, n - 1]
        got = {1: [], -1: []}
        while True:
            step = int(rng.choice([1, -1]))
            k = claim(counter, step)
            if k is None:
                assert claim(counter, -step) is None
                break
            got[step].append(k)
        assert sorted(got[1] + got[-1]) == list(range(n))
        assert got[1] == sorted(got[1]) and got[-1] == sorted(got[-1], reverse=True)
        if got[1] and got[-1]:
            assert max(got[1]) < min(got[-1])


def test_two_workers_give_the_sequential_spectrum(tmp_path, pulse12, params, spectrum12):
    """Two pulses on two spawned workers, one from the top, one from the bottom: the second
    starts from the default search, not from the first; both must give the eigenvalue of the
    sequential solve (same grid, unpinned)."""
    from slippulse.core.h5io import write_pulse
    from slippulse.spectrum.pulse import read_spectrum
    from slippulse.spectrum.family import run_spectrum
    f = str(tmp_path / "fam.h5")
    base = pulse12.to_pulse()
    for q in (1.2, 1.19):
        write_pulse(f, replace(base, tau_d_ratio=q), params)
    seen = []
    rep = run_spectrum(f, levels=0, min_points=0, extra=False, pin_translation=False,
                       workers=2, progress=lambda lab, res, st: seen.append(lab))
    assert sorted(seen) == ["td1.1900", "td1.2000"] and not rep.failed
    ref = spectrum12.leading
    for lab in ("td1.2000", "td1.1900"):
        st = read_spectrum(f, lab)
        assert st["status"] == "converged"
        assert complex(st["sigma"][0]) == pytest.approx(ref, rel=1e-9)


def test_cli_refuses_bad_worker_counts(tmp_path, pulse12, params):
    import cli_inproc

    from slippulse.core.h5io import write_pulse
    good = tmp_path / "one.h5"
    write_pulse(str(good), pulse12.to_pulse(), params)
    cases = [(["--workers", "0"], "workers=0 is invalid"),
             (["--threads", "0"], "threads=0 is invalid"),
             (["--workers", "2", "--count-workers", "2"], "use one of them")]
    for args, msg in cases:
        r = cli_inproc.run(["steady", "stability", good, "-q", *args])
        assert r.returncode == 2, (args, r.stderr)
        assert msg in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_newton_onto_a_real_eigenvalue_never_carries_a_subnormal_imaginary_part():
    """Quadratic convergence squares Im σ at each step (1e-17, 1e-34, ... 1e-318): a subnormal
    imaginary part then slowed every kernel assembly 20× (stop 37). Iterates of Newton onto a
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


def test_a_worker_whose_parent_is_gone_stops(monkeypatch):
    """A spawned worker outlives a SIGKILL or SIGTERM of the command (its `finally` does not
    run): it checks its parent between pulses and stops once it has been re-parented."""
    from slippulse.spectrum import family as sf
    done = []
    monkeypatch.setattr(sf, "_pulse_result",
                        lambda lab, *a, **k: (done.append(lab), (None, None, None))[1])
    ppids = iter([100, 100, 100, 1, 1, 1])          # the parent dies after the second pulse
    monkeypatch.setattr(sf.os, "getppid", lambda: next(ppids))

    class Q:
        def __init__(self):
            self.items = []

        def put(self, x):
            self.items.append(x)
    q = Q()
    sf._chunk_worker([(f"p{k}", None) for k in range(4)], None, (None, None), {}, q)
    assert done == ["p0", "p1"] and [x[0] for x in q.items] == ["p0", "p1"]
