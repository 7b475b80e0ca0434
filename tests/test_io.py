"""``szdyn.io.staged_output``: a set of files moved into place only once all of it is made."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from szdyn.errors import UserInputError
from szdyn.io import make_output_dir, staged_output


def test_staged_files_are_moved_in_with_last_ones_last_and_old_files_kept(tmp_path, monkeypatch):
    dest = tmp_path / "out"
    (dest / "sub").mkdir(parents=True)
    (dest / "sub" / "old.csv").write_text("old")
    (dest / "keep.txt").write_text("mine")
    (dest / "a.json").write_text("previous")
    moved = []
    real_replace = os.replace

    def spy(src, dst):
        moved.append(os.path.relpath(dst, dest))
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", spy)
    with staged_output(dest, last=("a.json", "z.csv")) as stage:
        assert stage.parent == dest and stage.name.startswith(".partial-")
        for rel in ("a.json", "b.csv", "z.csv", "sub/new.csv", "sub/deeper/x.csv"):
            (stage / rel).parent.mkdir(parents=True, exist_ok=True)
            (stage / rel).write_text(rel)
        assert not (dest / "b.csv").exists()   # nothing in place before the block ends
    assert moved == ["b.csv", "sub/deeper/x.csv", "sub/new.csv", "a.json", "z.csv"]
    assert (dest / "a.json").read_text() == "a.json" and (dest / "sub" / "deeper" / "x.csv").is_file()
    assert (dest / "sub" / "old.csv").read_text() == "old" and (dest / "keep.txt").read_text() == "mine"
    assert sorted(p.name for p in dest.iterdir()) == ["a.json", "b.csv", "keep.txt", "sub", "z.csv"]


def test_a_file_the_set_owns_but_the_new_set_lacks_is_removed_before_the_last(tmp_path, monkeypatch):
    dest = tmp_path / "out"
    dest.mkdir()
    for name in ("a.json", "plot.png", "optional.png", "keep.txt"):
        (dest / name).write_text("previous")
    events = []
    real_replace, real_unlink = os.replace, Path.unlink

    def spy_replace(src, dst):
        events.append(("moved", os.path.relpath(dst, dest)))
        real_replace(src, dst)

    def spy_unlink(self, *a, **k):
        events.append(("removed", os.path.relpath(self, dest)))
        real_unlink(self, *a, **k)

    monkeypatch.setattr(os, "replace", spy_replace)
    monkeypatch.setattr(Path, "unlink", spy_unlink)
    with staged_output(dest, last=("a.json",), owns=("a.json", "plot.png", "optional.png")) as stage:
        for rel in ("a.json", "plot.png"):
            (stage / rel).write_text("new")
        assert (dest / "optional.png").read_text() == "previous"   # nothing removed before the end
    # the earlier run's optional plot is gone before the new a.json says the set is complete;
    # a file the set does not own stays
    assert events == [("moved", "plot.png"), ("removed", "optional.png"), ("moved", "a.json")]
    assert sorted(p.name for p in dest.iterdir()) == ["a.json", "keep.txt", "plot.png"]
    assert (dest / "keep.txt").read_text() == "previous"


def test_a_failed_block_removes_no_owned_file(tmp_path):
    dest = tmp_path / "out"
    dest.mkdir()
    (dest / "optional.png").write_text("previous")
    with pytest.raises(RuntimeError):
        with staged_output(dest, owns=("optional.png",)) as stage:
            (stage / "a.json").write_text("new")
            raise RuntimeError("a run failed")
    assert [p.name for p in dest.iterdir()] == ["optional.png"]


@pytest.mark.parametrize("in_the_way", ["dir-at-file", "file-at-dir"])
def test_a_place_taken_is_refused_before_anything_moves(tmp_path, in_the_way):
    dest = tmp_path / "out"
    dest.mkdir()
    (dest / "a.csv").write_text("old a")
    if in_the_way == "dir-at-file":
        (dest / "z.json").mkdir()   # where a new file goes
    else:
        (dest / "sub").write_text("a file")   # where a new directory goes
    with pytest.raises(UserInputError, match="the new results were not written"):
        with staged_output(dest) as stage:
            (stage / "a.csv").write_text("new a")
            (stage / "z.json").write_text("new z")
            (stage / "sub").mkdir()
            (stage / "sub" / "c.csv").write_text("new c")
    assert (dest / "a.csv").read_text() == "old a"   # not half moved: old and new not mixed
    assert not [p for p in dest.iterdir() if p.name.startswith(".partial-")]


def test_a_failing_block_moves_nothing_and_a_file_dest_is_refused(tmp_path):
    dest = tmp_path / "out"
    with pytest.raises(RuntimeError):
        with staged_output(dest) as stage:
            (stage / "a.csv").write_text("new")
            raise RuntimeError("a run failed")
    assert not dest.exists()            # made by the call, empty: removed (nested ones too)
    with pytest.raises(RuntimeError):
        with staged_output(tmp_path / "new" / "deeper"):
            raise RuntimeError("a run failed")
    assert list(tmp_path.iterdir()) == []
    dest.mkdir()                        # there before the call: kept, as it was
    with pytest.raises(RuntimeError):
        with staged_output(dest):
            raise RuntimeError("a run failed")
    assert dest.is_dir() and list(dest.iterdir()) == []
    (tmp_path / "f").write_text("x")
    for d in (tmp_path / "f", tmp_path / "f" / "sub"):
        with pytest.raises(UserInputError, match="f is a file"):
            with staged_output(d):
                pass


@pytest.mark.parametrize("via", ["staged_output", "make_output_dir"])
def test_an_output_directory_the_system_refuses_is_a_clear_error(tmp_path, via):
    """A name over the file system's 255-byte limit: a UserInputError naming the directory, not
    an OSError traceback."""
    dest = tmp_path / "a" / ("x" * 300) / "b"
    with pytest.raises(UserInputError, match=r"cannot create the output directory \(File name too long\)"):
        if via == "make_output_dir":
            make_output_dir(dest)
        else:
            with staged_output(dest):
                pass
    assert list(tmp_path.iterdir()) == []


def test_the_directories_made_before_a_refusal_are_removed(tmp_path, monkeypatch):
    """mkdir makes the parents, then fails on the last (as a read-only or full file system
    would): the parents it made are removed, what was there before stays."""
    (tmp_path / "kept").mkdir()
    real = Path.mkdir

    def mkdir(self, *args, **kw):
        real(self.parent, parents=True, exist_ok=True)
        raise PermissionError(13, "Permission denied", str(self))
    monkeypatch.setattr(Path, "mkdir", mkdir)
    with pytest.raises(UserInputError, match=r"d: cannot create the output directory \(Permission denied\)"):
        make_output_dir(tmp_path / "kept" / "a" / "b" / "c" / "d")
    assert [p.name for p in tmp_path.rglob("*")] == ["kept"]


def test_make_output_dir_says_what_it_made(tmp_path):
    assert make_output_dir(tmp_path / "a" / "b") == [tmp_path / "a" / "b", tmp_path / "a"]
    assert make_output_dir(tmp_path / "a") == []
    (tmp_path / "f").write_text("")
    with pytest.raises(UserInputError, match=r"f is a file, not a directory"):
        make_output_dir(tmp_path / "f" / "g")
