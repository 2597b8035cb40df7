"""Agent use of platesynth: the MCP server (``platesynth mcp``), its guardrails and jobs, and the skill's reference.

Parts: :mod:`~platesynth.agent.workspace` (paths inside the workspace, limits), :mod:`~platesynth.agent.jobs`
(long work as jobs), :mod:`~platesynth.agent.server` (the tools and resources; needs the ``mcp`` package, the
``agent`` extra) and :mod:`~platesynth.agent.reference` (the skill's parameter reference, generated from the
catalogue). docs/agents.md describes them.
"""
