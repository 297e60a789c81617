"""Small helpers shared by the commands: progress bars and output checks."""
from __future__ import annotations

import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator

import click

from kukaid.errors import KukaidError


@contextmanager
def progress(total: float, label: str) -> Iterator[Callable[[float], None]]:
    """A progress bar on stderr; yields ``update(done)`` taking the absolute amount done."""
    with click.progressbar(length=max(int(total * 1000), 1), label=label, file=sys.stderr,
                           show_eta=True) as bar:
        state = {"pos": 0}

        def update(done: float) -> None:
            pos = min(int(done * 1000), bar.length)
            if pos > state["pos"]:
                bar.update(pos - state["pos"])
                state["pos"] = pos

        yield update


def refuse_overwrite(path: Path, force: bool) -> None:
    """Recorded data is never lost: refuse to replace an existing log unless --force."""
    if path.exists() and not force:
        raise KukaidError(f"{path}: already exists; choose another name or pass --force to replace it")
