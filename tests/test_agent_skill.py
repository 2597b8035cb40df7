"""The agentskills.io skill in skills/platesynth: valid by `agentskills validate`, its reference generated and current."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from platesynth.agent.reference import REFERENCE_NAME, parameter_reference
from platesynth.cli import app

SKILL = Path(__file__).resolve().parents[1] / "skills" / "platesynth"
REFERENCE = SKILL / "references" / REFERENCE_NAME


def _frontmatter() -> tuple[dict, str]:
    text = (SKILL / "SKILL.md").read_text(encoding="utf-8")
    match = re.match(r"^---\n(.*?)\n---\n(.*)$", text, re.S)
    assert match, "SKILL.md starts with YAML frontmatter between --- lines"
    return yaml.safe_load(match[1]), match[2]


def test_the_skill_passes_agentskills_validate():
    pytest.importorskip("skills_ref")
    result = subprocess.run([sys.executable, "-m", "skills_ref.cli", "validate", str(SKILL)], capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr + result.stdout
    assert "Valid skill" in result.stdout


def test_the_frontmatter_holds_only_the_specifications_fields():
    meta, body = _frontmatter()
    assert set(meta) <= {"name", "description", "license", "compatibility", "metadata"}
    assert meta["name"] == SKILL.name == "platesynth"
    assert 0 < len(meta["description"]) <= 1024 and len(meta.get("compatibility", "")) <= 500
    assert all(isinstance(k, str) and isinstance(v, str) for k, v in meta.get("metadata", {}).items())
    assert len(body.splitlines()) < 500
    for link in re.findall(r"\]\(([^)]+)\)", body):
        assert (SKILL / link).is_file(), f"SKILL.md links to a missing file: {link}"


def test_the_skill_names_the_servers_tools():
    pytest.importorskip("mcp")
    import anyio

    from platesynth.agent.server import build_server
    from platesynth.agent.workspace import Workspace

    async def names(tmp: Path) -> set[str]:
        return {tool.name for tool in await build_server(Workspace.create(tmp)).list_tools()}

    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        tools = anyio.run(names, Path(tmp))
    _, body = _frontmatter()
    listed = re.search(r"Tools:\s*(.*?)\.\s+Resources:", body, re.S)
    assert listed, "SKILL.md lists the tools after 'Tools:'"
    assert set(re.findall(r"`([a-z_]+)`", listed[1])) == tools


def test_the_parameter_reference_is_current():
    assert REFERENCE.read_text(encoding="utf-8") == parameter_reference(), (
        f"{REFERENCE} is stale: run `platesynth skill reference` and commit it"
    )
    from platesynth.scene import parameter_names

    text = REFERENCE.read_text(encoding="utf-8")
    assert all(f"`{name}`" in text for name in parameter_names())


def test_skill_reference_command_writes_and_checks(tmp_path):
    out = tmp_path / "references" / "parameters.md"
    runner = CliRunner()
    stale = runner.invoke(app, ["skill", "reference", "--out", str(out), "--check"])
    assert stale.exit_code == 1 and "stale" in stale.stderr and len(stale.stderr.strip().splitlines()) == 1
    assert runner.invoke(app, ["skill", "reference", "--out", str(out)]).exit_code == 0
    assert out.read_text(encoding="utf-8") == parameter_reference()
    assert runner.invoke(app, ["skill", "reference", "--out", str(out), "--check"]).exit_code == 0
    out.write_text(out.read_text(encoding="utf-8").replace("plaques.radius_mm", "plaques.radius"), encoding="utf-8")
    assert runner.invoke(app, ["skill", "reference", "--out", str(out), "--check"]).exit_code == 1


def test_docs_list_every_tool():
    pytest.importorskip("mcp")
    import tempfile

    import anyio

    from platesynth.agent.server import build_server
    from platesynth.agent.workspace import Workspace

    async def names(tmp: Path) -> set[str]:
        return {tool.name for tool in await build_server(Workspace.create(tmp)).list_tools()}

    with tempfile.TemporaryDirectory() as tmp:
        tools = anyio.run(names, Path(tmp))
    text = (SKILL.parents[1] / "docs" / "agents.md").read_text(encoding="utf-8")
    table = text[text.index("## Tools"):text.index("## Resources")]
    documented = {name for row in table.splitlines() if row.startswith("| `")
                  for name in re.findall(r"`([a-z_]+)`", row.split("|")[1])}
    assert documented == tools
