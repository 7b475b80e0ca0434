"""Atomic file output: a reader sees the old file or the complete new one, never a part; and a
set of files written elsewhere and moved in only once all of them are made."""
from __future__ import annotations

import errno
import json
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator, Mapping, Sequence

import numpy as np


def _default_mode() -> int:
    """Mode of a newly created file under the current umask (mkstemp would give 0600)."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` via a temp file in the same directory and ``os.replace``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, _default_mode())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return path


def atomic_write_text(path, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


def write_json(path, obj) -> Path:
    """JSON with NaN/inf refused (they are not JSON and would hide a failure)."""
    return atomic_write_text(path, json.dumps(obj, indent=2, allow_nan=False, sort_keys=False) + "\n")


def write_csv(path, columns: Mapping[str, np.ndarray]) -> Path:
    """Columns of equal length as a plain CSV with one header row (units live beside it, in
    the JSON that describes the file, so that any CSV reader can load it)."""
    names = list(columns)
    data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    if not np.all(np.isfinite(data)):
        bad = [n for n in names if not np.all(np.isfinite(columns[n]))]
        raise ValueError(f"refusing to write non-finite values to {path} (columns {bad})")
    lines = [",".join(names)]
    body = "\n".join(",".join(f"{v:.10g}" for v in row) for row in data)
    return atomic_write_text(path, "\n".join(lines) + "\n" + body + "\n")


def make_output_dir(dest) -> list:
    """Create the output directory ``dest`` and the missing ones above it.

    Returns
    -------
    list of Path
        The directories this call created, innermost first (for :func:`_remove_empty` after a
        failure).

    Raises
    ------
    UserInputError
        ``dest`` or a directory above it is a file, or ``dest`` cannot be created (no
        permission, a read-only or virtual file system, a name too long); nothing is left
        created.
    """
    from .errors import UserInputError

    dest = Path(dest)
    made = []
    try:
        for p in (dest, *dest.parents):   # (mkdir would fail on a file anywhere above, as a traceback)
            if p.exists() and not p.is_dir():
                raise UserInputError(f"{p} is a file, not a directory")
        made = [p for p in (dest, *dest.parents) if not p.exists()]   # innermost first
        dest.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        _remove_empty(made)
        raise UserInputError(f"{dest}: cannot create the output directory ({exc.strerror or exc})") from None
    return made


def _remove_empty(made) -> None:
    """Remove the directories ``made`` (innermost first) that exist and are empty."""
    for p in made:
        try:
            p.rmdir()
        except OSError as exc:
            if exc.errno not in (errno.ENOENT, errno.ENAMETOOLONG):   # one never made: go on
                break


@contextmanager
def staged_output(dest, last: Sequence[str] = (), owns: Sequence[str] = ()) -> Iterator[Path]:
    """Write a set of files into a staging directory inside ``dest``; move them in at the end.

    A run that fails or is interrupted part-way leaves ``dest`` as it was (the earlier results
    are neither lost nor mixed with new ones); only when the ``with`` block ends normally are
    the staged files moved into ``dest`` one by one (``os.replace``, subdirectories merged),
    the names in ``last`` last and in that order (a reader that checks for the last file sees a
    complete set). Files of ``dest`` that the new set does not replace are kept, except those
    named in ``owns``: they belong to such a set, so one the new set lacks is an earlier run's
    (a plot the new run had no data for) and is removed, before the ``last`` names move in.

    Parameters
    ----------
    dest : path-like
        Output directory; created if missing.
    last : sequence of str
        Relative paths (in the staged set) to move after all others.
    owns : sequence of str
        Relative paths that only this kind of set writes into ``dest``: removed where the new
        set does not have them.

    Yields
    ------
    Path
        The staging directory (hidden, ``.partial-*``; removed at the end either way, and with
        it, after a failure, the directories this call created, where they are empty).

    Raises
    ------
    UserInputError
        ``dest`` (or a directory above it) is a file, or a new file's place in it is taken by a directory (or a
        directory's by a file). Checked before anything is moved, so nothing is mixed. Also when
        ``dest`` cannot be created or written in (permissions, a name too long).
    """
    from .errors import UserInputError

    dest = Path(dest)
    made = make_output_dir(dest)
    try:
        stage = Path(tempfile.mkdtemp(prefix=".partial-", dir=dest))
    except OSError as exc:   # a directory one may not write in
        _remove_empty(made)
        raise UserInputError(f"{dest}: cannot write in the output directory ({exc.strerror or exc})") from None
    done = False
    try:
        yield stage
        order = {name: k + 1 for k, name in enumerate(last)}
        files = sorted((p.relative_to(stage).as_posix() for p in stage.rglob("*") if p.is_file()),
                       key=lambda n: (order.get(n, 0), n))
        for rel in files:   # all checked before the first move
            target = dest / rel
            if target.is_dir():
                raise UserInputError(f"{target} is a directory where the new file {rel} goes; move it away "
                                     "(the new results were not written)")
            for parent in target.relative_to(dest).parents:
                if (dest / parent).exists() and not (dest / parent).is_dir():
                    raise UserInputError(f"{dest / parent} is a file where the new directory of {rel} goes; "
                                         "move it away (the new results were not written)")
        stale = [dest / rel for rel in owns if rel not in files and (dest / rel).is_file()]
        for rel in files:
            if rel in order and stale:
                for p in stale:   # before the first of `last`: its reader sees no earlier run's file
                    p.unlink()
                stale = []
            target = dest / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(stage / rel, target)
        for p in stale:
            p.unlink()
        done = True
    finally:
        shutil.rmtree(stage, ignore_errors=True)
        if not done:
            # a failed first run leaves no empty output directory behind (what was there stays)
            _remove_empty(made)
