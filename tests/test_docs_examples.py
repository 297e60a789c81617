"""Every shell example of README.md and docs/*.md runs as written, so a changed option breaks CI
and not a user.

The convention of the pages' fenced blocks:

* ```` ```sh ````: run by this test with bash (``-euo pipefail``), in order within a page, in a
  scratch folder of the page, with the venv's ``kukaid`` first on PATH and ``KUKAID_SHARED`` set
  to the real datasets' folder (``../shared`` beside the repository unless set); a block that
  names ``KUKAID_SHARED`` or ``../shared`` is skipped when the datasets are absent;
* ```` ```sh-robot ```` needs a real controller (or its recordings), ```` ```sh-cluster ```` a
  running Dask cluster, ```` ```sh-make ```` is the project's own ``make demo`` / ``make test``,
  ```` ```sh-bench ```` a benchmark that takes minutes (its ``--quick`` size is run by a test):
  shown, not run;
* ```` ```text ````, ```` ```json ````, ```` ```python ```` ...: not shell; a block without a label
  is refused, so no shell example escapes the test by accident.

The pages run two at a time (the suite itself uses one core).
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from shared_data import SHARED

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", re.M | re.S)
NOT_RUN = {"sh-robot", "sh-cluster", "sh-make", "sh-bench"}
NOT_SHELL = {"text", "json", "python", "krl", "csv", "toml", "yaml", "ini"}


def blocks(page: Path) -> list[tuple[str, str, int]]:
    """``(label, body, line)`` of every fenced block of ``page``."""
    text = page.read_text()
    return [(m.group(1).strip(), m.group(2), text.count("\n", 0, m.start()) + 1) for m in FENCE.finditer(text)]


def _needs_data(body: str) -> bool:
    return "KUKAID_SHARED" in body or "../shared" in body


def run_page(page: Path, workdir: Path) -> tuple[list[str], list[str]]:
    """Run the page's ``sh`` blocks in order in ``workdir``: (failures, skipped blocks)."""
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
           "KUKAID_SHARED": str(SHARED), "KUKAID_DEMO_KVP": "0"}
    env.pop("KUKAID_DEBUG", None)
    failures, skipped = [], []
    for label, body, line in blocks(page):
        if label != "sh":
            continue
        where = f"{page.relative_to(ROOT)}:{line}"
        if _needs_data(body) and not (SHARED / "datasets").is_dir():
            skipped.append(where)
            continue
        t0 = time.monotonic()
        r = subprocess.run(["bash", "-euo", "pipefail", "-c", body], cwd=workdir, env=env, capture_output=True,
                           text=True, timeout=600, stdin=subprocess.DEVNULL)
        if r.returncode != 0:
            failures.append(f"{where}: exit {r.returncode} after {time.monotonic() - t0:.1f} s\n{body}\n"
                            f"--- stderr (end) ---\n{r.stderr[-2000:]}")
            break  # the page's later blocks build on this one
    return failures, skipped


def test_every_block_is_labelled():
    """A fence without a label, or with one the convention does not know, hides an example."""
    bad = [f"{p.relative_to(ROOT)}:{line}: ```{label}" for p in PAGES for label, _, line in blocks(p)
           if label not in {"sh", *NOT_RUN, *NOT_SHELL}]
    assert bad == []


def test_trace_loads_shown_give_the_gear_ratios():
    """New-user trial 13: real-controller.md showed `kukaid load REC_NextGenDrive#1.dat -o trace.h5`, which a
    KR C4's recording refuses (its drives record motor-side positions, beyond 720 degrees: 'give the gear
    ratios'); every KUKA Trace load shown (not run: sh-robot) gives --gear-ratio."""
    shown = [(f"{page.relative_to(ROOT)}:{line}", cmd) for page in PAGES for label, body, line in blocks(page)
             if label.startswith("sh") for cmd in body.splitlines()
             if re.match(r"\s*kukaid load \S+\.(dat|r64)\b", cmd)]
    assert shown and not [w for w, cmd in shown if "--gear-ratio" not in cmd], shown


def test_readme_is_short_and_links_every_page():
    """README.md stays a front page (at most 250 lines); its "Where to read on" links every page
    of docs/ (a new page gets a row there) and no page that does not exist."""
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 250
    links = set(re.findall(r"\]\((docs/[^)#]+)", readme))
    pages = {p.relative_to(ROOT).as_posix() for p in PAGES[1:]}
    assert sorted(links - pages) == [], "README links pages that do not exist"
    assert sorted(pages - links) == [], "pages of docs/ missing from README's \"Where to read on\""


#: the pages that take longest, started first so that the two at a time end together (seconds on the
#: shared 2-core machine: robot.md 23, fleet.md 16, robot-fit.md 9, the others 1-6; in the pages'
#: order robot.md started last, 47 s for 43)
SLOW_FIRST = ("robot.md", "fleet.md", "robot-fit.md")


class PageRuns:
    """Pages run by :func:`run_page`, each once per session in its own scratch folder under ``root``,
    two at a time: ``run(pages)`` -> {page: (failures, skipped, scratch folder)} (the session fixture
    ``doc_pages`` of conftest.py; test_fleet_docs.py reads docs/fleet.md's run)."""

    def __init__(self, root: Path) -> None:
        self.root, self.done = root, {}

    def run(self, pages: list[Path]) -> dict[Path, tuple[list[str], list[str], Path]]:
        todo = sorted((p for p in dict.fromkeys(pages) if p not in self.done),
                      key=lambda p: SLOW_FIRST.index(p.name) if p.name in SLOW_FIRST else len(SLOW_FIRST))

        def one(page: Path):
            d = _scratch(self.root, page)
            return page, (*run_page(page, d), d)
        with ThreadPoolExecutor(max_workers=2) as pool:
            self.done.update(pool.map(one, todo))
        return {p: self.done[p] for p in pages}


def test_shell_examples_run(doc_pages):
    """Each page in its own scratch folder; two pages at a time."""
    pages = [p for p in PAGES if any(label == "sh" for label, _, _ in blocks(p))]
    failures = [f for fs, _, _ in doc_pages.run(pages).values() for f in fs]
    assert failures == [], "\n\n".join(failures)


def _scratch(tmp_path: Path, page: Path) -> Path:
    d = tmp_path / page.stem
    d.mkdir()
    return d


if __name__ == "__main__":  # python tests/test_docs_examples.py docs/fit.md: one page, its times
    import tempfile

    for arg in sys.argv[1:] or [str(p) for p in PAGES]:
        with tempfile.TemporaryDirectory() as d:
            t0 = time.monotonic()
            fs, sk = run_page(Path(arg).resolve(), Path(d))
            print(f"{arg}: {'ok' if not fs else 'FAILED'} in {time.monotonic() - t0:.1f} s"
                  + (f", skipped {sk}" if sk else ""))
            for f in fs:
                print(f)
