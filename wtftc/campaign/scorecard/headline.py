"""The README's table of the committed scorecards: each verdict of each card in
``results/`` (its ``scorecard.json``), side by side, written between two markers by
``make headline`` and held to the cards by a test. Nothing in it is typed by hand."""

from __future__ import annotations

import json
from pathlib import Path

BEGIN, END = "<!-- results:begin -->", "<!-- results:end -->"
#: the groups whose verdicts the table shows, in this order
GROUPS = ("normal_production", "actuator_faults", "sensor_faults")


def cards(root: Path) -> list[tuple[Path, dict]]:
    """Every committed card under ``root`` (``results/``): (its folder, its report), in
    the folders' order."""
    out = []
    for path in sorted(Path(root).glob("*/scorecard.json")):
        out.append((path.parent, json.loads(path.read_text("utf-8"))))
    return out


def _cell(r: dict | None) -> str:
    if r is None or r.get("ratio") is None:
        return "—"
    if r.get("low") is None:
        return f"{r['ratio']:.3g} ({r['verdict']})"
    verdict = r["verdict"] if r["verdict"] != "tie" else "**tie**"
    return f"{r['ratio']:.3g} ({r['low']:.3g}–{r['high']:.3g}) {verdict}"


def _in_openfast(doc: dict, group: str, key: str) -> str:
    """A screened card's confirmation of one verdict: OpenFAST's ratio, interval and
    verdict over the confirmed scenarios both engines held, the screen's ratio there, and
    whether OpenFAST's interval agrees (stats.agreement); empty where none."""
    conf = doc["groups"].get(group, {}).get("confirmed") or {}
    r = next((r for r in conf.get("metrics", []) if r["metric"] == key), None)
    if r is None or r.get("ratio") is None or r.get("agree") is None:
        return ""
    said = f"**{r['agree']}**" if r["agree"] == "disagrees" else r["agree"]
    return (f"; OpenFAST over {r['n_pairs']} confirmed: {_cell(r)}, screen "
            f"{r['screen_ratio']:.3g} there ({said})")


def _how(doc: dict) -> str:
    screen = doc.get("screen")
    how = "OpenFAST" if screen is None else \
        "screened on wtftc's plant, what decides each verdict confirmed in OpenFAST"
    return how


def table(found: list[tuple[Path, dict]], base: Path) -> str:
    """The Markdown: a line per card (what, against what, how, its code), then each
    group's metrics as rows and the cards as columns."""
    if not found:
        return "No scorecard is committed yet (results/README.md)."
    lines = ["Each cell: the ratio controller / ROSCO over the scenarios both held, its 90 % "
             "bootstrap interval over the seeds, and the verdict (**tie** where the interval "
             "holds 1). Lower is better but for the power and the energy. A screened card's "
             "verdicts are the reduced plant's over every scenario. After each: OpenFAST's "
             "ratio over the confirmed scenarios both engines held, the screen's over the "
             "same, and whether OpenFAST's interval lies on the screen's side of 1 "
             "(agrees), the other (disagrees) or holds 1. The confirmed scenarios are each "
             "metric's most against and most for its verdict and those whose outcomes "
             "differ: not a sample of the whole. Each report lists the runs either engine "
             "lost. From the committed scorecards:", ""]
    for folder, doc in found:
        rel = folder.relative_to(base).as_posix()
        lines.append(f"- [`{rel}`]({rel}/scorecard.md): `{doc['controller']}` against "
                     f"`{doc['baseline']}` on the {doc['turbine'] or 'nrel5mw'}, "
                     f"{_how(doc)}; generated code `{doc['generated_code_sha256']}`")
    heads = [doc["turbine"] or "nrel5mw" for _, doc in found]
    lines += ["", "| group | metric | " + " | ".join(heads) + " |",
              "|---|---|" + "---|" * len(heads)]
    for group in GROUPS:
        keys = []
        for _, doc in found:
            for r in doc["groups"].get(group, {}).get("metrics", []):
                if (r["metric"], r["what"], r["unit"]) not in keys:
                    keys.append((r["metric"], r["what"], r["unit"]))
        for key, what, unit in keys:
            cells = [_cell(next((r for r in doc["groups"].get(group, {}).get("metrics", [])
                                 if r["metric"] == key), None))
                     + _in_openfast(doc, group, key) for _, doc in found]
            if any(c != "—" for c in cells):
                lines.append(f"| {group} | {what} [{unit}] | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def with_table(text: str, block: str) -> str:
    """``text`` (the README) with ``block`` between its markers, which it must hold."""
    if BEGIN not in text or END not in text or text.index(BEGIN) > text.index(END):
        raise ValueError(f"the README has no {BEGIN} ... {END} block")
    head, rest = text.split(BEGIN, 1)
    return head + BEGIN + "\n" + block + "\n" + END + rest.split(END, 1)[1]


def main(readme: Path, root: Path) -> str:
    """The README's text with the table of the cards under ``root`` (not written)."""
    readme = Path(readme)
    return with_table(readme.read_text("utf-8"), table(cards(root), readme.parent))
