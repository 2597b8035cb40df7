"""The skill's parameter reference (``skills/platesynth/references/parameters.md``), generated from the catalogue.

``platesynth skill reference`` writes it; ``platesynth skill reference --check`` (and ``tests/test_agent_skill.py``)
fails when the file differs from what the catalogue gives now, so the reference an agent reads cannot drift from
the parameters the code accepts.
"""

from __future__ import annotations

import json
from typing import Any

from platesynth.schemas import ParameterInfo, catalogue, presets

REFERENCE_NAME = "parameters.md"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _range(row: ParameterInfo) -> str:
    values = row.range
    if row.type == "category" or len(values) != 2 or not all(isinstance(v, (int, float)) for v in values):
        return ", ".join(str(v) for v in values)
    return f"{values[0]:g} to {values[1]:g}"


def _default(value: Any) -> str:
    return json.dumps(value, separators=(", ", ": "))


def parameter_reference() -> str:
    """The Markdown reference of every scene parameter and preset, from the catalogue (deterministic)."""
    rows = catalogue().parameters
    sections: dict[str, list[ParameterInfo]] = {}
    for row in rows:
        sections.setdefault(row.name.split(".")[0], []).append(row)
    lines = [
        "# Scene parameters",
        "",
        "Generated from the parameter catalogue by `platesynth skill reference`; do not edit by hand (a test fails",
        "when this file is stale). The same table, as JSON: the MCP tool `catalogue`, or `platesynth scene catalogue",
        "--json`.",
        "",
        "A value is a constant, a range `[low, high]` drawn uniformly, or one of the forms `{normal: [mean, sd]}`,",
        "`{lognormal: [median, sigma]}`, `{choice: [a, b, ...]}` (see docs/scene.md); ranges are checked against the",
        "valid range below. Override one with `overrides` (MCP) or `--set section.name=value` (command line), e.g.",
        "`{\"plaques.radius_mm\": [0.5, 1.0]}`. Parameters whose description starts with \"each\" are drawn again for",
        "every well, plaque, scratch, speck or blot; the others once per plate.",
        "",
        f"{len(rows)} parameters in {len(sections)} sections: {', '.join(sections)}.",
        "",
        "## Presets",
        "",
        "| preset | what it is |",
        "|---|---|",
    ]
    lines += [f"| `{p.name}` | {_cell(p.description)} |" for p in presets().presets]
    for section, members in sections.items():
        lines += ["", f"## {section}", "", "| parameter | type | unit | valid range | default | description |",
                  "|---|---|---|---|---|---|"]
        for row in members:
            lines.append(
                f"| `{row.name}` | {row.type} | {_cell(row.unit) or '-'} | {_cell(_range(row))} | "
                f"`{_cell(_default(row.default))}` | {_cell(row.description)} |"
            )
    return "\n".join(lines) + "\n"
