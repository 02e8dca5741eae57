"""sim/mavlink imports no module that imports it back: the command handlers and the dialects
take the vehicle as a Host (host.py) instead of importing vehicle.py, which imports them."""

from __future__ import annotations

import ast
from pathlib import Path

import sim.mavlink

ROOT = Path(sim.mavlink.__file__).parent


def _module(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = [p for p in rel.parts if p != "__init__"]
    return ".".join(["sim.mavlink", *parts])


def _imports(path: Path) -> set[str]:
    """The sim.mavlink modules a file imports at module level, `if TYPE_CHECKING:` blocks
    included (a cycle of type names is a cycle of ideas too); not imports inside functions."""
    here = _module(path).split(".")
    package = here if path.name == "__init__.py" else here[:-1]
    out = set()
    body = []
    for node in ast.parse(path.read_text()).body:
        body.extend(node.body if isinstance(node, ast.If) else [node])
    for node in body:
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.startswith("sim.mavlink"):
                names = [f"{mod}.{a.name}" for a in node.names]
                out |= {n for n in names if (ROOT.parent.parent / (n.replace(".", "/") + ".py")).exists()} or {mod}
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("sim.mavlink")}
    return out - {_module(path)}


def test_no_import_cycles_in_sim_mavlink() -> None:
    graph = {_module(p): _imports(p) for p in ROOT.rglob("*.py")}
    assert "sim.mavlink.vehicle" not in graph["sim.mavlink.commands"]

    def visit(node: str, stack: list[str], done: set[str]) -> None:
        if node in stack:
            raise AssertionError("import cycle: " + " -> ".join(stack[stack.index(node):] + [node]))
        if node in done or node == "sim.mavlink":
            return
        for nxt in sorted(graph.get(node, ())):
            visit(nxt, [*stack, node], done)
        done.add(node)

    done: set[str] = set()
    for node in sorted(graph):
        visit(node, [], done)
