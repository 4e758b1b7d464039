"""workbench.files.atomic_write: whole files or none, nothing left behind."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from workbench.files import atomic_write


def test_replaces_the_file_and_leaves_no_temporary(tmp_path) -> None:
    target = tmp_path / "deep" / "data.txt"
    atomic_write(target, lambda name: Path(name).write_text("one"))
    atomic_write(target, lambda name: Path(name).write_text("two"), durable=False)
    assert target.read_text() == "two"
    assert [p.name for p in target.parent.iterdir()] == ["data.txt"]


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path) -> None:
    target = tmp_path / "data.txt"
    target.write_text("old")

    def half_then_fail(name: str) -> None:
        Path(name).write_text("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        atomic_write(target, half_then_fail)
    with pytest.raises(FileNotFoundError):  # the writer made no file: nothing to sync
        atomic_write(target, lambda name: None)
    assert target.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["data.txt"]


def test_the_writer_creates_the_file_with_the_usual_permissions(tmp_path) -> None:
    plain = tmp_path / "plain.txt"
    plain.write_text("x")
    seen = []

    def write(name: str) -> None:
        seen.append(name)
        assert not os.path.exists(name)  # a compiler or a library creates it itself
        Path(name).write_text("x")

    atomic_write(tmp_path / "atomic.txt", write)
    assert Path(seen[0]).parent == tmp_path and Path(seen[0]).name.startswith(".atomic.txt.")
    assert seen[0].endswith(".tmp")  # what the results store clears after a crash
    assert (tmp_path / "atomic.txt").stat().st_mode == plain.stat().st_mode
