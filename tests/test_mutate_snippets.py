"""`make mutate` (benches/mutate.py) edits the package by exact snippets and runs named tests: each snippet must
stand once in its file and each test must be collected, or the suite stops at the first stale one and tries none."""

from __future__ import annotations

import functools
import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@functools.cache
def _mutations() -> list:
    spec = importlib.util.spec_from_file_location("benches_mutate", ROOT / "benches" / "mutate.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module.MUTATIONS


@pytest.mark.parametrize("mutation", _mutations(), ids=lambda m: m.name)
def test_each_mutations_snippet_stands_once_and_changes_the_code(mutation) -> None:  # noqa: ANN001
    for file, old, new in mutation.edits:
        text = (ROOT / "autosar_cli" / file).read_text()
        assert text.count(old) == 1, f"{mutation.name}: {file} holds its snippet {text.count(old)} times"
        assert old != new


def test_each_mutations_tests_are_collected() -> None:
    """The node ids that must kill the mutations name tests pytest collects (a parameter's id included)."""
    wanted = sorted({t for m in _mutations() for t in m.tests})
    files = sorted({t.split("::")[0] for t in wanted})
    listed = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:xdist",
                             "-p", "no:cacheprovider", *files], cwd=ROOT, capture_output=True, text=True).stdout
    collected = {line.strip() for line in listed.splitlines()}
    # a node id without a parameter's id runs all of them
    assert [t for t in wanted if t not in collected and not any(c.startswith(t + "[") for c in collected)] == []


def test_the_documents_state_as_many_mutations_as_the_list_holds() -> None:
    import re

    stated = {name: re.findall(r"(\d+) (?:curated mutations|in ~\d+ min on 2 cores|are caught)",
                               (ROOT / name).read_text()) for name in ("README.md", "Makefile", "docs/ARCHITECTURE.md")}
    assert stated == {name: [str(len(_mutations()))] for name in stated}
