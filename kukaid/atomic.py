"""Atomic file output: write to temporary files beside the targets, rename them on success."""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import Iterator

from kukaid.errors import KukaidError


def check_output(path: str | os.PathLike) -> Path:
    """Refuse an output path that cannot be a plain file: an existing folder, device or pipe
    (renaming onto ``/dev/null`` would replace the device), or a parent that is not a folder."""
    target = Path(path)
    if target.exists() and not target.is_file():
        kind = "a folder" if target.is_dir() else "not a regular file"
        raise KukaidError(f"{target}: is {kind}; give a file name to write")
    for parent in target.parents:
        if parent.exists():
            if not parent.is_dir():
                raise KukaidError(f"{target}: {parent} is not a folder")
            break
    return target


def check_writable(path: str | os.PathLike) -> Path:
    """Make sure a file can be created beside ``path`` (its folder is created if missing), before
    work that cannot be repeated (a robot run) produces it."""
    target = check_output(path)
    folder = target.parent if str(target.parent) else Path(".")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".probe", dir=folder)
        os.close(fd)
        os.unlink(tmp)
    except OSError as e:
        raise KukaidError(f"{target}: cannot write: {e.strerror or e}") from None
    return target


def make_folder(folder: Path) -> list[Path]:
    """Make ``folder`` and its missing parents; returns those it made (outermost first), for
    :func:`remove_folders` to take away again when the command that wanted them fails."""
    made = [p for p in reversed([folder, *folder.parents]) if not p.exists()]
    folder.mkdir(parents=True, exist_ok=True)
    return made


def remove_folders(made: list[Path]) -> None:
    """Remove the folders :func:`make_folder` made, deepest first, each only if it is (still) empty."""
    for f in reversed(made):
        with contextlib.suppress(OSError):
            f.rmdir()


@contextlib.contextmanager
def atomic_paths(*paths: str | os.PathLike) -> Iterator[tuple[Path, ...]]:
    """Yield one temporary path per target, in the target's folder (created if missing); rename
    them all onto the targets only when the block succeeds.

    On any exception every temporary file is removed and the targets are left untouched, so a
    failed command never leaves a half-written output file, nor some of its outputs without the
    others.  An ``OSError`` about a temporary file is reported as the target's.
    """
    targets = [check_output(p) for p in paths]
    if len({t.resolve() for t in targets}) != len(targets):
        raise KukaidError(f"{targets[0]}: the same file is given for two outputs")
    tmps: list[Path] = []
    made: list[Path] = []  # folders made for the outputs: a command that fails leaves none behind
    umask = os.umask(0)
    os.umask(umask)
    for target in targets:
        folder = target.parent if str(target.parent) else Path(".")
        try:
            made += make_folder(folder)
            fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=folder)
        except OSError as e:
            _remove(tmps, made)
            raise KukaidError(f"{target}: cannot write: {e.strerror or e}") from None
        os.close(fd)
        tmps.append(Path(tmp))
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; an output file gets the usual permissions
    try:
        yield tuple(tmps)
        for tmp, target in zip(tmps, targets):
            os.replace(tmp, target)
    except OSError as e:
        _remove(tmps, made)
        name = str(e.filename) if e.filename is not None else None
        for tmp, target in zip(tmps, targets):
            if name is None or name == str(tmp):
                raise KukaidError(f"{target}: cannot write: {e.strerror or e}") from None
        raise
    except BaseException:
        _remove(tmps, made)
        raise


def _remove(paths: list[Path], folders: list[Path] = ()) -> None:
    """Remove the temporary files ``paths``, then the ``folders`` made for them (deepest first, each
    only if it is empty)."""
    for p in paths:
        with contextlib.suppress(FileNotFoundError):
            p.unlink()
    remove_folders(list(folders))


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """:func:`atomic_paths` for one target: yields its temporary path."""
    with atomic_paths(path) as (tmp,):
        yield tmp


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def write_texts_atomic(files: dict[str | os.PathLike, str]) -> None:
    """Write several text files, all or none."""
    with atomic_paths(*files) as tmps:
        for tmp, text in zip(tmps, files.values()):
            tmp.write_text(text)
