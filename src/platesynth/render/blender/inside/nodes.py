"""Small helpers to build node trees from code (materials, geometry nodes, compositor)."""

from __future__ import annotations

from typing import Any

import bpy


def add(tree: bpy.types.NodeTree, node_type: str, name: str | None = None, **properties: Any) -> bpy.types.Node:
    """Add a node of ``node_type``, set its properties (``operation=...``) and optionally name and label it."""
    node = tree.nodes.new(node_type)
    if name:
        node.name = node.label = name
    for key, value in properties.items():
        setattr(node, key, value)
    return node


def socket(sockets: Any, key: str | int) -> bpy.types.NodeSocket:
    """The enabled socket called ``key`` (nodes such as Math or Random Value hide several of the same name)."""
    if isinstance(key, int):
        return [s for s in sockets if s.enabled][key]
    for candidate in sockets:
        if candidate.enabled and (candidate.identifier == key or candidate.name == key):
            return candidate
    raise KeyError(f"no enabled socket {key!r} among {[s.name for s in sockets if s.enabled]}")


def link(tree: bpy.types.NodeTree, source: Any, target: Any) -> None:
    """Connect ``source`` (a node: its first output; or a socket) to ``target`` (a node's first input, or a socket)."""
    if isinstance(source, bpy.types.Node):
        source = socket(source.outputs, 0)
    if isinstance(target, bpy.types.Node):
        target = socket(target.inputs, 0)
    tree.links.new(source, target)


def feed(tree: bpy.types.NodeTree, node: bpy.types.Node, **inputs: Any) -> bpy.types.Node:
    """Set or link the inputs of ``node`` by name: sockets and nodes are linked, anything else is a default value.

    Names with spaces are given with underscores (``Offset_Scale=2``); a trailing digit picks among same-named
    sockets (``Value_1`` is the second enabled ``Value``).
    """
    for key, value in inputs.items():
        target = _input_socket(node, key)
        if isinstance(value, (bpy.types.Node, bpy.types.NodeSocket)):
            link(tree, value, target)
        else:
            target.default_value = value
    return node


def _input_socket(node: bpy.types.Node, key: str) -> bpy.types.NodeSocket:
    enabled = [s for s in node.inputs if s.enabled]
    name = key.replace("_", " ")
    for candidate in enabled:
        if candidate.name == name or candidate.identifier == key:
            return candidate
    base, _, index = key.rpartition("_")
    if index.isdigit():
        same = [s for s in enabled if s.name == base.replace("_", " ")]
        if int(index) < len(same):
            return same[int(index)]
    raise KeyError(f"{node.bl_idname} has no input {key!r}; inputs: {[s.name for s in enabled]}")


def math(tree: bpy.types.NodeTree, operation: str, a: Any, b: Any = None, c: Any = None) -> bpy.types.Node:
    """A Math node ``operation(a, b, c)``; each operand is a number, a node or a socket."""
    node = add(tree, "ShaderNodeMath", operation=operation)
    operands = {"Value": a, "Value_1": b, "Value_2": c}
    feed(tree, node, **{key: value for key, value in operands.items() if value is not None})
    return node


def vector_math(tree: bpy.types.NodeTree, operation: str, a: Any, b: Any = None) -> bpy.types.Node:
    """A Vector Math node ``operation(a, b)``; operands are vectors, nodes or sockets."""
    node = add(tree, "ShaderNodeVectorMath", operation=operation)
    operands = {"Vector": a, "Vector_1": b}
    feed(tree, node, **{key: value for key, value in operands.items() if value is not None})
    return node


def output(node: bpy.types.Node, name: str | int) -> bpy.types.NodeSocket:
    """The enabled output socket ``name`` (or the ``name``-th enabled one) of ``node``."""
    return socket(node.outputs, name)
