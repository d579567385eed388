"""core.atomic: a file replaced whole is either the old one or the new one, never a mix, and no
temporary file stays behind."""
import os

import pytest

from slippulse.core.atomic import replacing, replacing_open


def _listing(d):
    return sorted(os.listdir(d))


def test_a_writer_that_fails_leaves_the_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "out.csv"
    target.write_text("old\n")
    with pytest.raises(RuntimeError):
        with replacing_open(str(target)) as fh:
            fh.write("new, half written")
            raise RuntimeError("interrupted")
    assert target.read_text() == "old\n"
    assert _listing(tmp_path) == ["out.csv"]


def test_an_interrupt_inside_replacing_removes_the_temporary_file(tmp_path):
    target = tmp_path / "a.h5"
    with pytest.raises(KeyboardInterrupt):
        with replacing(str(target), suffix=".h5") as tmp:
            assert os.path.dirname(tmp) == str(tmp_path) and tmp.endswith(".h5")
            open(tmp, "w").write("partial")
            raise KeyboardInterrupt
    assert not target.exists()
    assert _listing(tmp_path) == []


def test_a_clean_write_replaces_the_file_and_keeps_its_permissions(tmp_path):
    target = tmp_path / "t.bin"
    target.write_bytes(b"old")
    os.chmod(target, 0o640)
    with replacing_open(str(target), "wb") as fh:
        fh.write(b"new")
    assert target.read_bytes() == b"new"
    assert os.stat(target).st_mode & 0o777 == 0o640
    assert _listing(tmp_path) == ["t.bin"]


def test_a_new_file_gets_the_umask_permissions_not_mkstemps(tmp_path):
    target = tmp_path / "n.txt"
    mask = os.umask(0o022)
    try:
        with replacing_open(str(target)) as fh:
            fh.write("x")
    finally:
        os.umask(mask)
    assert os.stat(target).st_mode & 0o777 == 0o644


def test_replacing_open_refuses_a_mode_that_would_not_write_a_new_file(tmp_path):
    with pytest.raises(ValueError, match="mode='a'"):
        with replacing_open(str(tmp_path / "x"), "a"):
            pass
