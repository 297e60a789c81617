"""Reading the toolkit's JSON inputs (parameter files, trajectories, limits, simulator truth)."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from kukaid.errors import KukaidError


def read_json(path: str | Path, error: type[KukaidError] = KukaidError) -> Any:
    """Parse the JSON file ``path``; raise ``error`` with one line naming the file and the problem."""
    path = Path(path)
    try:
        text = path.read_text(errors="replace")
    except FileNotFoundError:
        raise error(f"{path}: no such file") from None
    except OSError as e:
        raise error(f"{path}: cannot read: {e.strerror}") from None
    if not text.strip():
        raise error(f"{path}: empty file")
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise error(f"{path}: not valid JSON (line {e.lineno}, column {e.colno}: {e.msg})") from None


def jsonable(x: Any) -> Any:
    """``x`` with numpy scalars made Python numbers and non-finite floats made None (JSON has no NaN)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x
