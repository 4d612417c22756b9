"""Write docs/BENCHMARKS.md from benches/results/*.json: every figure with the command and machine that made it.
Usage: python benches/benchmarks_md.py [--results benches/results] [--output docs/BENCHMARKS.md] [--max-rows 4]

One section per JSON file, in file-name order. The command is the ``Usage:`` line of the bench script whose
docstring names that JSON file, the description its first line; the machine is what the JSON recorded
(``machine``, ``cores``, ``host_*``, ``python``), or says that it recorded none. Scalars become a
key/value table; lists of records a table with one column per scalar field (at most ``--max-rows`` rows;
the JSON holds the rest); per-run lists of numbers are shown as their count and range.
"""

from __future__ import annotations

import argparse
import ast
import json
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
MACHINE_KEYS = ("machine", "cores", "cpus", "python", "host_before", "host_after")
MAX_COLUMNS = 12
MAX_NAMED = 1  #: named records (a summary's groups) shown per table: the aggregate "all" alone
MAX_ROWS = 2
LEAD_PREFIXES = ("drives", "sarmin_af_", "sarmin_")  #: columns shown first, in this order
MAX_TEXT = 200  #: characters of a text value (a note) shown
PER_RUN_KEYS = {"rows", "trials", "mutations"}  #: per-drive / per-trial records: in the JSON where a summary exists
SUMMARY_KEYS = {"summary", "table"}


def bench_scripts(benches: Path) -> dict[str, tuple[str, str]]:
    """JSON file name -> (first docstring line, usage command) of the bench script that writes it."""
    out: dict[str, tuple[str, str]] = {}
    for script in sorted(p for p in benches.glob("*.py") if p.name != Path(__file__).name):
        doc = ast.get_docstring(ast.parse(script.read_text())) or ""
        lines = doc.splitlines()
        usage = next((ln.removeprefix("Usage:").strip() for ln in lines if ln.startswith("Usage:")),
                     f"python benches/{script.name}")
        for word in doc.replace("``", " ").split():
            name = word.strip(".,;:()[]`")
            if name.endswith(".json"):
                out.setdefault(Path(name).name, (lines[0] if lines else "", usage))
        if script.name.startswith("bench_"):
            out.setdefault(script.stem.removeprefix("bench_") + ".json", (lines[0] if lines else "", usage))
    return out


def cell(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list) and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        if not value:
            return "[]"
        if len(value) <= 3:
            return ", ".join(cell(v) for v in value)
        return f"{len(value)} values, {cell(min(value))} .. {cell(max(value))}"
    if isinstance(value, dict):
        return ", ".join(f"{k} {cell(v)}" for k, v in value.items() if is_scalar(v))
    text = str(value).replace("\n", " ")
    if len(text) > MAX_TEXT:  # a note the length of a page: its opening here, the whole of it in the JSON
        text = text[:MAX_TEXT].rsplit(" ", 1)[0] + " … (the JSON has it whole)"
    return text.replace("|", "\\|")


def is_scalar(value: Any) -> bool:
    return not isinstance(value, dict | list) or isinstance(value, list) and not any(
        isinstance(v, dict | list) for v in value)


def table(header: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header),
            *("| " + " | ".join(r) + " |" for r in rows), ""]


def records_table(records: list[dict[str, Any]], max_rows: int, names: list[str] | None = None,
                  corner: str = "") -> list[str]:
    """One row per record (headed by its name from ``names``, if given, under the column head ``corner``), one
    column per scalar field."""
    columns: list[str] = []
    for rec in records:
        columns += [k for k, v in rec.items() if is_scalar(v) and k not in columns]
    # the product's own columns before the baselines' (the paper's summaries hold none_*, ins_* first)
    columns = sorted(columns, key=lambda k: next((i for i, p in enumerate(LEAD_PREFIXES) if k.startswith(p)),
                                                 len(LEAD_PREFIXES)))
    shown = columns[:MAX_COLUMNS]
    rows = [[cell(rec.get(k, "")) for k in shown] for rec in records[:max_rows]]
    if names is not None:
        shown, rows = [corner, *shown], [[f"**{n}**", *r] for n, r in zip(names, rows, strict=False)]
    lines = table(shown, rows)
    notes = []
    if len(records) > max_rows:
        notes.append(f"{len(records) - max_rows} more rows")
    if len(columns) > len(shown):
        notes.append("more fields: " + ", ".join(columns[len(shown):]))
    nested = sorted({k for rec in records for k, v in rec.items() if not is_scalar(v)})
    if nested:
        notes.append("per-row groups: " + ", ".join(nested))
    if notes:
        lines += [f"({'; '.join(notes)}: see the JSON.)", ""]
    return lines


def section(data: Any, max_rows: int, depth: int = 0) -> list[str]:
    """Markdown of one JSON value: scalars as a table, records as tables, dicts of dicts as sub-headings."""
    lines: list[str] = []
    if isinstance(data, list):
        return records_table([r for r in data if isinstance(r, dict)], max_rows) if data else []
    scalars = [(k, v) for k, v in data.items() if is_scalar(v) and k not in MACHINE_KEYS and k != "benchmark"]
    if scalars:  # one line: a key/value table would cost a line per figure
        lines += ["; ".join(f"{k} **{cell(v)}**" for k, v in scalars), ""]
    for key, value in data.items():
        if is_scalar(value) or key in MACHINE_KEYS:
            continue
        if key in PER_RUN_KEYS and isinstance(value, list) and SUMMARY_KEYS & data.keys():
            note = f"{len(value)} {key} behind the summary (see the JSON)"
            if scalars:
                lines[0] += f"; {note}"  # on the figures' line: a paragraph per note cost 2 lines a section
            else:
                lines[:0] = [f"{note[0].upper()}{note[1:]}.", ""]  # the section's first line: it joins the command's
            continue
        if isinstance(value, dict) and all(is_scalar(v) for v in value.values()):
            if len(lines) >= 2 and lines[-1] == "" and lines[-2] and not lines[-2].startswith(("|", "#", "(")):
                lines[-2] += f"; **{key}**: {cell(value)}"  # small groups share the figures' paragraph
            else:
                lines += [f"**{key}**: {cell(value)}", ""]
            continue
        if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            # records under a key: the key in the table's note (a heading would cost 2 lines)
            table_lines = records_table(value, max_rows)
            if table_lines[-2].startswith("("):
                table_lines[-2] = f"({key}: " + table_lines[-2][1:]
            else:
                table_lines += [f"({key}: see the JSON.)", ""]
            lines += table_lines
            continue
        if isinstance(value, dict) and value and all(isinstance(v, dict) for v in value.values()):
            # a table of named records, its key in the corner (a heading would cost 2 lines); beyond MAX_NAMED of
            # them, the first ones and the aggregate "all" (not where it repeats the one other group)
            names = list(value)
            if len(names) == 2 and "all" in value:
                names = [n for n in names if n != "all"]
            if len(names) > MAX_NAMED:
                names = names[:MAX_NAMED - 1] + (["all"] if "all" in value else names[MAX_NAMED - 1:MAX_NAMED])
            lines += records_table([value[n] for n in names], len(names), names=names, corner=key)
            if len(names) < len(value):
                more = f"{len(value) - len(names)} more groups"
                if len(lines) >= 2 and lines[-1] == "" and lines[-2].endswith(": see the JSON.)"):
                    lines[-2] = lines[-2][: -len(": see the JSON.)")] + f"; {more}: see the JSON.)"
                else:
                    lines += [f"({more}: see the JSON.)", ""]
            continue
        sub = section(value, max_rows, depth + 1)
        if len(sub) == 2 and not sub[1] and not sub[0].startswith(("|", "#", "(")):
            # one paragraph needs no heading (which costs 2 lines), and shares the figures' paragraph
            if len(lines) >= 2 and lines[-1] == "" and lines[-2] and not lines[-2].startswith(("|", "#", "(")):
                lines[-2] += f"; **{key}**: {sub[0]}"
            else:
                lines += [f"**{key}**: {sub[0]}", ""]
        else:
            lines += [f"{'#' * min(3 + depth, 6)} {key}", "", *sub]
    return lines


def machine_of(data: dict[str, Any]) -> str:
    found = [f"{k} {cell(data[k])}" for k in MACHINE_KEYS if k in data]
    return "; ".join(found) if found else "not recorded in the JSON"


def render(results: Path, max_rows: int) -> str:
    scripts = bench_scripts(HERE)
    out = ["# Benchmarks", "",
           "Generated by `python benches/benchmarks_md.py` (`make benchmarks-md`) from `benches/results/*.json`; "
           "do not edit by hand. Each section names the command that wrote its figures and the machine it recorded "
           "(wall-clock seconds on it). The headline figures, each with its command: "
           "[RESULTS.md](RESULTS.md#at-a-glance).", ""]
    for path in sorted(results.glob("*.json")):
        data = json.loads(path.read_text())
        title, usage = scripts.get(path.name, ("", "(no bench script names this file)"))
        out += [f"## {path.stem}"]  # the paragraph follows the heading directly: a line per section
        machine = machine_of(data) if isinstance(data, dict) else "-"
        # the script's one-line purpose, its command and the section's first line of figures in one paragraph (a
        # table needs the blank line before it)
        body = section(data, max_rows)
        out += [(f"{title} " if title else "") + f"Command `{usage}`; machine: {machine}; data "
                f"[`benches/results/{path.name}`](../benches/results/{path.name})."]
        if body and body[0] and not body[0].startswith(("|", "#", "(")):
            out[-1] += " Figures: " + body.pop(0)  # one paragraph, one line
            if body and not body[0]:
                body.pop(0)
            while len(body) > 1 and body[0].startswith("**") and not body[1]:  # a group's figures: the same line
                out[-1] += "; " + body.pop(0)
                body.pop(0)
        out += [""] + body if body else []
    # a heading may follow a paragraph or a table directly (an ATX heading interrupts either, and a paragraph may
    # follow one): no blank line between them
    out = [line for i, line in enumerate(out) if not (line == "" and 0 < i < len(out) - 1 and out[i - 1]
                                                       and (out[i + 1].startswith("#") or out[i - 1].startswith("#")))]
    return "\n".join(out).rstrip() + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=HERE / "results")
    parser.add_argument("--output", type=Path, default=HERE.parent / "docs" / "BENCHMARKS.md")
    parser.add_argument("--max-rows", type=int, default=MAX_ROWS)
    args = parser.parse_args()
    args.output.write_text(render(args.results, args.max_rows))
    print(f"wrote {args.output} ({len(args.output.read_text().splitlines())} lines)")


if __name__ == "__main__":
    main()
