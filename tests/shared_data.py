"""Where the real datasets are: ``$KUKAID_SHARED``, else ``../shared`` beside the repository.
Tests that need them skip when they are absent."""
from __future__ import annotations

import os
from pathlib import Path

SHARED = Path(os.environ.get("KUKAID_SHARED") or Path(__file__).resolve().parents[2] / "shared")
