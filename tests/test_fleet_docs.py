"""docs/fleet.md: its ```sh examples run as written, in order, from a scratch folder (```sh-cluster
examples need a running cluster and are not run)."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def sh_blocks(text: str) -> list[str]:
    return re.findall(r"^```sh\n(.*?)^```", text, flags=re.S | re.M)


def test_fleet_doc_examples_run(tmp_path):
    blocks = sh_blocks((ROOT / "docs" / "fleet.md").read_text())
    assert len(blocks) >= 3
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    for block in blocks:
        r = subprocess.run(["bash", "-euo", "pipefail", "-c", block], cwd=tmp_path, env=env, capture_output=True,
                           text=True, timeout=300)
        assert r.returncode == 0, f"{block}\n{r.stderr[-2000:]}"
    assert (tmp_path / "fleet" / "wear.pdf").read_bytes()[:4] == b"%PDF"
