"""Reference values live in data files with provenance, not in code constants."""
import os
import tomllib

import pytest

from slippulse.core import reference

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_every_data_file_names_its_source():
    names = [f[:-5] for f in os.listdir(reference.DATA_DIR) if f.endswith(".toml")]
    assert "paper_scaling" in names
    for n in names:
        src = reference.load(n)["source"]
        assert src.get("kind") in ("paper", "run") and (src.get("where") or src.get("commit"))


def test_paper_scaling_reads_the_file(tmp_path, monkeypatch):
    (tmp_path / "paper_scaling.toml").write_text(
        '[source]\nkind = "paper"\nwhere = "test"\n[values]\ntau_star = 1.5\na_v = 2.0\na_G = 3.0\n')
    monkeypatch.setattr(reference, "DATA_DIR", str(tmp_path))
    reference.load.cache_clear()
    try:
        assert reference.paper_scaling() == {"tau_star": 1.5, "a_v": 2.0, "a_G": 3.0}
        (tmp_path / "bare.toml").write_text("[values]\nx = 1\n")
        with pytest.raises(ValueError, match="source"):
            reference.load("bare")
    finally:
        reference.load.cache_clear()


def test_sbi_rates_file_has_provenance_and_rows():
    with open(os.path.join(ROOT, "dynamic", "results", "sbi_growth_rates.toml"), "rb") as fh:
        data = tomllib.load(fh)
    assert data["source"]["commit"] and data["source"]["commands"]
    rows = data["rates"]
    assert rows and all({"tau_d_ratio", "s", "err", "domain"} <= set(r) for r in rows)
