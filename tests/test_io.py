"""``szdyn.io.staged_output``: a set of files moved into place only once all of it is made."""
from __future__ import annotations

import os

import pytest

from szdyn.errors import UserInputError
from szdyn.io import staged_output


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
