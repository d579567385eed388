"""The one writer of slippulse files (core.h5io.atomic_update: a file lock, a write-ahead
journal): two writer processes and a reader on one file lose no pulse and the reader never sees
a half-written file; a kill at any point of a commit leaves the file as before or as after; an
append costs the pulse, not the file; a full disk or a read-only file leaves it unchanged."""
import os
import signal
import subprocess
import sys
import textwrap

import h5py
import numpy as np
import pytest

from slippulse.core import h5io
from slippulse.core.journal import JournaledFile, journal_path, recover
from slippulse.core.params import DEFAULT as P

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from test_analysis import _synthetic_pulse  # noqa: E402

_PRELUDE = textwrap.dedent(f"""
    import sys
    sys.path.insert(0, {HERE!r})
    from test_analysis import _synthetic_pulse
    from slippulse.core import h5io
    from slippulse.core.params import DEFAULT as P
""")


def _ratios(k, n):
    """n distinct τ_d/τ_min for writer k (interleaved between the writers)."""
    return [round(1.02 + 0.004 * (2 * i + k), 4) for i in range(n)]


def _start(code, **env):
    return subprocess.Popen([sys.executable, "-c", _PRELUDE + textwrap.dedent(code)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, **env))


def test_two_writers_and_a_reader_lose_nothing(tmp_path):
    path = str(tmp_path / "fam.h5")
    h5io.write_pulse(path, _synthetic_pulse(1.2, 0.1, 0.1), P)
    h5io.atomic_update(path, lambda h5: h5.create_dataset("pad", data=np.zeros(2_000_000)))
    n = 12
    go = str(tmp_path / "go")
    writer = """
        import os, time
        while not os.path.exists({go!r}):
            time.sleep(0.01)
        for r in {ratios!r}:
            h5io.write_pulse({path!r}, _synthetic_pulse(r, 0.1, 0.1), P)
        print("wrote", len({ratios!r}))
    """
    reader = """
        import os, time
        while not os.path.exists({go!r}):
            time.sleep(0.01)
        reads, t0 = 0, time.time()
        while time.time() - t0 < 60:
            labels = h5io.list_pulses({path!r})
            for lab in labels:
                h5io.read_pulse({path!r}, lab)       # validated: raises on a half-written pulse
                reads += 1
            if len(labels) == {total}:
                break
        print("reads", reads, "labels", len(labels))
    """
    procs = [_start(writer.format(go=go, path=path, ratios=_ratios(k, n))) for k in (0, 1)]
    procs.append(_start(reader.format(go=go, path=path, total=2 * n + 1)))
    open(go, "w").close()
    outs = [p.communicate(timeout=300) for p in procs]
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err
    assert outs[2][0].split()[-1] == str(2 * n + 1), outs[2]
    labels = set(h5io.list_pulses(path))
    want = {h5io.pulse_label(r) for k in (0, 1) for r in _ratios(k, n)} | {"td1.2000"}
    assert labels == want
    for lab in labels:
        h5io.read_pulse(path, lab)
    assert not os.path.exists(journal_path(path))


@pytest.mark.parametrize("point,present", [("journal_torn", False), ("journal_written", True),
                                           ("file_half_written", True)])
def test_a_kill_during_a_commit_leaves_the_file_before_or_after(tmp_path, point, present):
    path = str(tmp_path / "fam.h5")
    h5io.write_pulse(path, _synthetic_pulse(1.2, 0.1, 0.1), P)
    before = open(path, "rb").read()
    p = _start(f"h5io.write_pulse({path!r}, _synthetic_pulse(1.1, 0.1, 0.1), P)",
               SLIPPULSE_KILL_AT=point)
    p.communicate(timeout=120)
    assert p.returncode == -signal.SIGKILL
    assert os.path.exists(journal_path(path))
    if point == "journal_torn":
        assert open(path, "rb").read() == before           # the file was never touched
    labels = h5io.list_pulses(path)                          # a reader recovers first
    assert ("td1.1000" in labels) == present
    assert not os.path.exists(journal_path(path))
    for lab in labels:
        h5io.read_pulse(path, lab)


def test_an_append_writes_the_pulse_not_the_file(tmp_path):
    """The journal of an append to a 160 MB file holds the pulse and some metadata pages."""
    path = str(tmp_path / "fam.h5")
    h5io.write_pulse(path, _synthetic_pulse(1.2, 0.1, 0.1), P)
    h5io.atomic_update(path, lambda h5: h5.create_dataset("pad", data=np.zeros(20_000_000)))
    pulse = _synthetic_pulse(1.1, 0.1, 0.1)
    jf = JournaledFile(path)
    with h5py.File(jf, "r+") as h5:
        grp = h5["pulses"].create_group("td1.1000")
        for name in h5io.DATASETS:
            grp.create_dataset(name, data=getattr(pulse, name))
    written = jf.commit()
    data = len(h5io.DATASETS) * pulse.xi.size * 8
    assert data < written < data + 200_000, (written, data)


def test_a_read_only_file_is_refused_before_anything_is_written(tmp_path):
    path = str(tmp_path / "fam.h5")
    h5io.write_pulse(path, _synthetic_pulse(1.2, 0.1, 0.1), P)
    os.chmod(path, 0o444)
    before = open(path, "rb").read()
    with pytest.raises(PermissionError) as exc:
        h5io.write_pulse(path, _synthetic_pulse(1.1, 0.1, 0.1), P)
    assert exc.value.filename == path
    assert open(path, "rb").read() == before
    assert sorted(os.listdir(tmp_path)) == [".fam.h5.lock", "fam.h5"]


def test_an_uncommitted_update_changes_nothing_and_a_torn_journal_is_discarded(tmp_path):
    path = str(tmp_path / "f.bin")
    with open(path, "wb") as fh:
        fh.write(b"a" * 10_000)
    jf = JournaledFile(path)
    jf.seek(9_000)
    jf.write(b"b" * 3_000)
    jf.seek(8_999)
    assert jf.read(3) == b"abb"                            # reads see the overlay
    jf.close()                                              # dropped: never committed
    assert open(path, "rb").read() == b"a" * 10_000
    assert recover(path) == "none"
    with open(journal_path(path), "wb") as fh:
        fh.write(b"SLPJRNL1 torn")
    assert recover(path) == "discarded"
    assert open(path, "rb").read() == b"a" * 10_000
    jf = JournaledFile(path)
    jf.seek(9_000)
    jf.write(b"b" * 3_000)
    jf.commit()
    assert open(path, "rb").read() == b"a" * 9_000 + b"b" * 3_000


def test_a_truncated_then_regrown_file_reads_zeros_where_it_was_cut(tmp_path):
    """HDF5 may shrink the file and grow it again in one session: the bytes between the cut and
    the new end read as zeros, before and after the commit."""
    path = str(tmp_path / "f.bin")
    with open(path, "wb") as fh:
        fh.write(b"a" * 20_000)
    jf = JournaledFile(path)
    jf.truncate(8_192)                                     # a page boundary
    jf.seek(12_000)
    jf.write(b"b" * 1_000)
    jf.seek(0)
    seen = jf.read()
    jf.commit()
    want = b"a" * 8_192 + bytes(12_000 - 8_192) + b"b" * 1_000
    assert seen == want
    assert open(path, "rb").read() == want
