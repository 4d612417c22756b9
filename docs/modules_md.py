"""docs/MODULES.md from the package's own docstrings: every module, one line each (``make modules-md``).

The line is the first sentence of the module's docstring, so the map says what the code says and cannot drift from
it; ``tests/test_docs.py`` fails where MODULES.md is stale.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "autosar_cli"
#: the stages in the order a drive goes through them, the simulator that feeds them last
ORDER = ["", "ingest", "store", "nav", "sar", "evaluate", "sim"]
#: a sentence ends at a full stop before a blank, not after an abbreviation
SENTENCE_END = re.compile(r"(?<!e\.g)(?<!i\.e)(?<!\bFig)(?<!\bSec)(?<!\betc)(?<!\beq)(?<!\beqs)\.(?:\s|$)")
ROLE = re.compile(r":(?:func|mod|class|meth|data|attr):`~?\.?([^`]+)`")


def first_sentence(path: Path) -> str:
    """The first sentence of ``path``'s module docstring, in Markdown (Sphinx roles and rst literals as code)."""
    doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    paragraph = " ".join(doc.strip().split("\n\n")[0].split())
    end = SENTENCE_END.search(paragraph)
    sentence = paragraph[: end.start()] if end else paragraph
    sentence = ROLE.sub(lambda m: f"`{m.group(1).rsplit('.', 1)[-1] if '.' in m.group(1) else m.group(1)}`", sentence)
    return sentence.replace("``", "`").replace("|", "\\|")


def render(package: Path = PACKAGE) -> str:
    """MODULES.md's text for the package at ``package``."""
    def stage(folder: Path) -> tuple[int, str]:
        name = "" if folder == package else folder.name
        return (ORDER.index(name) if name in ORDER else len(ORDER), name)

    folders = sorted({p.parent for p in package.rglob("*.py") if "__pycache__" not in p.parts}, key=stage)
    lines = ["# Modules", "",
             "Every module of `autosar_cli`, one line each: the first sentence of its docstring, in the order a drive",
             "goes through the stages (the simulator last). How the stages fit: [ARCHITECTURE.md](ARCHITECTURE.md).",
             "Generated from the code by `make modules-md` (`python docs/modules_md.py`).", ""]
    for folder in folders:
        rel = folder.relative_to(ROOT).as_posix()
        lines += [f"## `{rel}/`", "", first_sentence(folder / "__init__.py") + ".", "",
                  "| module | what it holds |", "|---|---|"]
        for path in sorted(folder.glob("*.py")):
            if path.name != "__init__.py":
                lines.append(f"| [`{path.name}`](../{rel}/{path.name}) | {first_sentence(path)} |")
        lines.append("")
    return "\n".join(lines)


def main() -> int:
    (ROOT / "docs" / "MODULES.md").write_text(render())
    print("docs/MODULES.md written")
    return 0


if __name__ == "__main__":
    sys.exit(main())
