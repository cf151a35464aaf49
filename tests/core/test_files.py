"""Atomic writes: a file appears whole or not at all, with the usual permissions."""

from __future__ import annotations

import os
import stat

import pytest

from negobs_gym.core.files import write_atomic, write_bytes_atomic, write_text_atomic


def test_write_creates_folders_and_leaves_no_temp_file(tmp_path) -> None:
    path = write_text_atomic(tmp_path / "sub" / "a.txt", "hello\n")
    assert path.read_text() == "hello\n"
    assert [p.name for p in path.parent.iterdir()] == ["a.txt"]
    write_bytes_atomic(path, b"again")
    assert path.read_bytes() == b"again"
    assert [p.name for p in path.parent.iterdir()] == ["a.txt"]


def test_a_failed_write_keeps_the_old_file_and_removes_its_temp_file(tmp_path) -> None:
    path = write_text_atomic(tmp_path / "result.json", "old")

    def half_then_fail(tmp) -> None:
        tmp.write_text("half")
        raise RuntimeError("killed mid-write")

    with pytest.raises(RuntimeError, match="killed mid-write"):
        write_atomic(path, half_then_fail)
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]


def test_the_temp_file_keeps_the_suffix_and_gets_umask_permissions(tmp_path) -> None:
    seen = []

    def write(tmp) -> None:  # writers such as model.save pick the format by the suffix
        seen.append(tmp)
        tmp.write_bytes(b"zip")

    path = write_atomic(tmp_path / "model.zip", write)
    assert seen[0].suffix == ".zip" and seen[0].parent == tmp_path and seen[0] != path
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask  # not mkstemp's 0600
