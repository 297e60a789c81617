"""docs/fleet.md: its ```sh examples run as written, in order, from a scratch folder (```sh-cluster
examples need a running cluster and are not run): the page's run of test_docs_examples.py (the
session fixture ``doc_pages``: each page runs once), and what they leave there."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def sh_blocks(text: str) -> list[str]:
    return re.findall(r"^```sh\n(.*?)^```", text, flags=re.S | re.M)


def test_fleet_doc_examples_run(doc_pages):
    page = ROOT / "docs" / "fleet.md"
    assert len(sh_blocks(page.read_text())) >= 3
    failures, skipped, scratch = doc_pages.run([page])[page]
    assert failures == [] and skipped == [], "\n\n".join(failures)
    assert (scratch / "fleet" / "wear.pdf").read_bytes()[:4] == b"%PDF"
