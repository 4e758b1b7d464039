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


def test_a_write_below_a_root_makes_its_missing_folders_and_none_through_a_link(
    tmp_path,
) -> None:
    """With ``root``, the folders are made when the write finds them missing (not checked
    and made at every write); a folder that is a link is refused before anything is
    written, however the path is spelt (the plain spelling takes the fast check)."""
    from workbench.files import LinkRefusedError, check_no_links

    out = tmp_path / "out"
    atomic_write(out / "runs" / "a.json", lambda name: Path(name).write_text("a"), root=out)
    atomic_write(out / "runs" / "b.json", lambda name: Path(name).write_text("b"), root=out)
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["a.json", "b.json"]
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (out / "series").symlink_to(elsewhere)
    spellings = [
        out / "series" / "x.parquet",  # plain: the fast check
        f"{out}/./series/x.parquet",  # '.': pathlib's way
        f"{out}//series//x.parquet",
    ]
    for spelt in spellings:
        with pytest.raises(LinkRefusedError, match="symbolic link"):
            check_no_links(spelt, out)
        with pytest.raises(LinkRefusedError, match="symbolic link"):
            atomic_write(spelt, lambda name: Path(name).write_text("x"), root=out)
    with pytest.raises(LinkRefusedError, match="'..'"):
        check_no_links(f"{out}/runs/../series/x.parquet", out)
    with pytest.raises(LinkRefusedError, match="not inside"):
        check_no_links(tmp_path / "outside" / "x", out)
    assert list(elsewhere.iterdir()) == []
    (out / "runs" / "c.json").symlink_to(elsewhere / "c")
    with pytest.raises(LinkRefusedError):
        check_no_links(out / "runs" / "c.json", out)
    check_no_links(out / "runs" / "new" / "deeper" / "d.json", out)  # not there yet: fine


def test_a_writers_own_missing_file_is_not_taken_for_a_missing_folder(tmp_path) -> None:
    """A FileNotFoundError of the writer itself (its folder exists) is raised as it is,
    the write not tried again."""
    calls = []

    def write(name: str) -> None:
        calls.append(name)
        Path(name + ".missing").read_text()

    with pytest.raises(FileNotFoundError):
        atomic_write(tmp_path / "x.txt", write, root=tmp_path)
    assert len(calls) == 1 and list(tmp_path.iterdir()) == []


def test_check_writable_says_a_folder_cannot_be_written_before_the_work(tmp_path) -> None:
    """`workbench record` into a read-only OUT ran every run again and then said they
    had failed; it now asks first. (A read-only folder cannot be made for root here, so a
    file and a missing folder stand in for it: the same OSError path.)"""
    from workbench.errors import ConfigError
    from workbench.files import check_writable

    check_writable(tmp_path)
    assert not list(tmp_path.iterdir())  # the probe leaves nothing
    afile = tmp_path / "afile"
    afile.write_text("")
    for folder in (afile, tmp_path / "missing"):
        with pytest.raises(ConfigError, match=f"cannot write into {folder}: "):
            check_writable(folder)
