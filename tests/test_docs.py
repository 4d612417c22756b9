"""docs/ describe the code as it is: short documents, no narrative of the work's history, links that resolve."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("*.md"))
MAX_LINES = 300
#: dated or numbered narrative: "2026-11-24", "third session", "round 3", "run C (...)"
HISTORY = re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b|\bsessions?\b|\bround \d|\brun [A-L]\b(?! *[=:])", re.IGNORECASE)
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def test_the_stage_documents_exist() -> None:
    names = {p.name for p in DOCS}
    assert {"ARCHITECTURE.md", "FORMATS.md", "NAVIGATION.md", "FOCUS.md", "EVALUATION.md", "BATCH.md",
            "BENCHMARKS.md"} <= names


@pytest.mark.parametrize("doc", DOCS, ids=[p.name for p in DOCS])
def test_doc_is_short_and_tells_no_history(doc: Path) -> None:
    lines = doc.read_text().splitlines()
    assert len(lines) <= MAX_LINES, f"{doc.name}: {len(lines)} lines"
    history = [f"{i}: {ln.strip()[:80]}" for i, ln in enumerate(lines, 1) if HISTORY.search(ln)]
    assert not history, f"{doc.name} narrates its history:\n" + "\n".join(history)


@pytest.mark.parametrize("doc", [*DOCS, ROOT / "README.md"], ids=[*(p.name for p in DOCS), "README.md"])
def test_relative_links_resolve(doc: Path) -> None:
    missing = [t for t in LINK.findall(doc.read_text()) if "://" not in t and not (doc.parent / t).exists()]
    assert not missing, f"{doc.name}: links to missing files {missing}"


def test_docstrings_tell_no_history() -> None:
    found = []
    for path in sorted((ROOT / "autosar_cli").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
                doc = ast.get_docstring(node) or ""
                found += [f"{path.relative_to(ROOT)}: {m.group(0)}" for m in HISTORY.finditer(doc)]
    assert not found, "docstrings that point at the work's history:\n" + "\n".join(found)


def test_readme_opens_with_a_picture() -> None:
    lines = [ln for ln in (ROOT / "README.md").read_text().splitlines() if ln.strip()]
    first_content = next(ln for ln in lines if not ln.startswith("#"))
    assert re.match(r"\s*(!\[|<img|<p|<a)", first_content), first_content
    pictures = re.findall(r"!\[[^\]]*\]\(([^)]+\.png)\)", (ROOT / "README.md").read_text())
    assert len(pictures) >= 2
    for rel in pictures:
        assert (ROOT / rel).stat().st_size <= 300_000, rel


def test_benchmarks_md_is_generated_from_the_results() -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location("benchmarks_md", ROOT / "benches" / "benchmarks_md.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    expected = module.render(ROOT / "benches" / "results", module.MAX_ROWS)
    assert (ROOT / "docs" / "BENCHMARKS.md").read_text() == expected, "stale docs/BENCHMARKS.md: run make benchmarks-md"
    n_results = len(list((ROOT / "benches" / "results").glob("*.json")))
    assert expected.count("Command `python benches/") == n_results  # every result names its command


def test_modules_md_is_generated_from_the_docstrings() -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location("modules_md", ROOT / "docs" / "modules_md.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    expected = module.render()
    assert (ROOT / "docs" / "MODULES.md").read_text() == expected, "stale docs/MODULES.md: run make modules-md"
    modules = [p for p in (ROOT / "autosar_cli").rglob("*.py") if p.name != "__init__.py"]
    assert expected.count("| [`") == len(modules) and "|  |" not in expected  # every module, each with its line


def test_code_points_at_sections_that_exist() -> None:
    """A reference like `docs/FOCUS.md, "Back-projection kernel"` in the code names a heading of that document."""
    cited = re.compile(r'docs/(\w+\.md),? "([^"]+)"')
    missing = []
    for path in sorted((ROOT / "autosar_cli").rglob("*.py")):
        for doc, section in cited.findall(path.read_text()):
            headings = [ln.lstrip("#").strip() for ln in (ROOT / "docs" / doc).read_text().splitlines()
                        if ln.startswith("#")]
            if section not in headings:
                missing.append(f"{path.relative_to(ROOT)}: {doc} \"{section}\"")
    assert not missing, "\n".join(missing)


def test_every_option_the_documents_give_a_command_is_one_it_takes() -> None:
    """`autosar CMD ... --opt` in README.md and docs/ (code spans and code blocks): CMD takes --opt."""
    from typer.main import get_command

    from autosar_cli.cli import app

    root = get_command(app)
    takes = {name: {o for p in [*cmd.params, *root.params] for o in (*p.opts, *p.secondary_opts)}
             for name, cmd in root.commands.items()}
    command = re.compile(r"autosar (?:--debug )?(" + "|".join(takes) + r")\b([^#]*)")
    unknown, given = [], 0
    for doc in [ROOT / "README.md", *DOCS]:
        text = doc.read_text()
        code = re.findall(r"`([^`\n]+)`", text) + [ln for block in re.findall(r"```[a-z]*\n(.*?)```", text, re.S)
                                                   for ln in block.splitlines()]
        for snippet in code:
            for m in command.finditer(snippet):
                options = re.findall(r"(?<![\w-])(--?[a-zA-Z][\w-]*)", re.split(r"&&|;|\|(?!\|)", m.group(2))[0])
                given += len(options)
                unknown += [f"{doc.name}: autosar {m.group(1)} {o}" for o in options if o not in takes[m.group(1)]]
    assert unknown == [] and given > 100


#: a test cited in a doc: `test_x.py::test_name`, `tests/test_x.py`, `test_name`, `*` for any name's part (a
#: placeholder such as `tests/test_<stage>_*.py` is not one)
TEST_CITATION = re.compile(r"(?<![\w/.])(?:tests/)?test_[\w*]*(?:\.py)?(?:::test_[\w*]+)?(?![<{])")


def test_every_cited_test_exists() -> None:
    tests = {p.name: set(re.findall(r"^\s*(?:async\s+)?def (test_\w+)", p.read_text(), re.MULTILINE))
             for p in sorted((ROOT / "tests").glob("*.py"))}
    every = set().union(*tests.values())
    stale = []
    for doc in [ROOT / "README.md", *DOCS]:
        for n, line in enumerate(doc.read_text().splitlines(), 1):
            for span in re.findall(r"`([^`]+)`", line):
                for cited in TEST_CITATION.findall(span):
                    file, _, name = cited.removeprefix("tests/").rpartition("::")
                    if name.endswith(".py"):
                        file, name = name, ""
                    files = [f for f in tests if re.fullmatch(file.replace("*", r"\w*"), f)] if file else list(tests)
                    names = set().union(*(tests[f] for f in files)) if files else set()
                    found = bool(files) and (not name or any(re.fullmatch(name.replace("*", r"\w*"), t) for t in names))
                    if not found:
                        stale.append(f"{doc.name}:{n}: {cited}")
    assert every and not stale, "docs cite tests that do not exist:\n" + "\n".join(stale)
