"""Atomic output and the data registry."""

import os

import pytest

from hyperlf import DataNotFoundError
from hyperlf._atomic import atomic_path, atomic_write_text
from hyperlf.datasets import ENV_VAR, data_root, dataset_path


def test_atomic_write_replaces_only_on_success(tmp_path):
    target = tmp_path / "sub" / "out.txt"
    atomic_write_text(target, "first")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("interrupted")
    assert target.read_text() == "first"
    assert sorted(p.name for p in target.parent.iterdir()) == ["out.txt"]


def test_data_root_errors(monkeypatch, tmp_path):
    monkeypatch.delenv(ENV_VAR, raising=False)
    with pytest.raises(DataNotFoundError, match=ENV_VAR):
        data_root()
    monkeypatch.setenv(ENV_VAR, str(tmp_path / "nope"))
    with pytest.raises(DataNotFoundError, match="not a folder"):
        data_root()
    monkeypatch.setenv(ENV_VAR, str(tmp_path))
    with pytest.raises(DataNotFoundError, match="known names"):
        dataset_path("antinous")
    (tmp_path / "hci4d" / "antinous").mkdir(parents=True)
    assert dataset_path("antinous") == tmp_path / "hci4d" / "antinous"
    assert os.fspath(dataset_path("hci4d")).endswith("hci4d")
