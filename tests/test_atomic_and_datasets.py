"""Atomic output and the data registry."""

import os

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from hyperlf import DataNotFoundError
from hyperlf._atomic import NAME_MAX, atomic_path, atomic_write_text, temporary_beside
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


@settings(max_examples=60, deadline=None,  # each example removes its own file
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(name=st.text(st.characters(blacklist_categories=("Cs", "Cc"), blacklist_characters="/"),
                    min_size=1, max_size=255),
       suffix=st.sampled_from(["", ".h5", ".hdf5", ".png"]),
       tag=st.sampled_from(["partial", "scratch"]))
def test_temporary_beside_fits_every_name_a_target_may_have(tmp_path, name, suffix, tag):
    """The temporary file beside any target name of at most 255 bytes is a name the file
    system takes, hidden, and starts with as much of the target's name as fits."""
    if len(os.fsencode(name)) > NAME_MAX or name in (".", ".."):
        return
    fd, tmp = temporary_beside(tmp_path / name, suffix, tag=tag)
    try:
        os.close(fd)
        got = os.path.basename(tmp)
        assert len(os.fsencode(got)) <= NAME_MAX and got.endswith(suffix)
        stem = got[1:got.rindex(f".{tag}-")]
        assert got.startswith(".") and name.startswith(stem) and stem
    finally:
        os.unlink(tmp)


def test_atomic_path_writes_a_target_whose_temporary_name_would_be_too_long(tmp_path):
    target = tmp_path / ("0" * 231 + ".hdf5")   # 236 bytes: + ".partial-XXXXXXXX.hdf5" > 255
    with atomic_path(target) as tmp:
        tmp.write_bytes(b"data")
    assert target.read_bytes() == b"data" and os.listdir(tmp_path) == [target.name]
