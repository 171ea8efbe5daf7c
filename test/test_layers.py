"""The package's layers, read from the source with ``ast`` (nothing is imported).

* no import cycle between modules of ``ltd_brake_ros`` (imports inside functions count: a
  dependency is a dependency; imports under ``if TYPE_CHECKING:`` do not, they never run);
* ROS (rclpy and the message packages of the ROS wheels) is imported at module level only under
  ``ros/``, so ``pip install .`` without the ROS wheels gives a working library and CLI;
* nothing under ``physics/`` imports rclpy, mcap, matplotlib or argparse, even lazily;
* only ``cli/`` imports argparse, and no library module imports the CLI or the ROS adapters.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "ltd_brake_ros"
ROS_PACKAGES = {"rclpy", "rosidl_parser", "rosidl_runtime_py", "std_msgs", "std_srvs",
                "rosgraph_msgs", "diagnostic_msgs", "builtin_interfaces", "rcl_interfaces",
                "ament_index_python"}


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or \
        (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def imports(name: str) -> list[tuple[str, bool]]:
    """``(imported module, at module level)`` for every import a module executes."""
    path = MODULES[name]
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: list[tuple[str, bool]] = []

    def visit(node, top: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                for sub in child.orelse:
                    visit(sub, top)
                continue
            if isinstance(child, ast.Import):
                found.extend((a.name, top) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = package.split(".")[: len(package.split(".")) - child.level + 1]
                    base = ".".join(base + ([child.module] if child.module else []))
                else:
                    base = child.module
                for a in child.names:  # `from . import verb` names a submodule
                    sub = f"{base}.{a.name}"
                    found.append((sub if sub in MODULES else base, top))
            inner = top and not isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                   ast.Lambda))
            visit(child, inner)

    visit(ast.parse(path.read_text(), str(path)), True)
    return found


GRAPH = {name: sorted({m for m, _ in imports(name) if m in MODULES and m != name})
         for name in MODULES}


def cycles(graph: dict[str, list[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in graph:
        if v not in index:
            connect(v)
    return out


def under(name: str, layer: str) -> bool:
    return name == f"ltd_brake_ros.{layer}" or name.startswith(f"ltd_brake_ros.{layer}.")


def test_the_walk_sees_the_package():
    # guards the checks below against an empty or broken walk
    assert {"ltd_brake_ros.simulator", "ltd_brake_ros.cli.main",
            "ltd_brake_ros.recording.writer"} <= set(MODULES)
    assert "ltd_brake_ros.cli.simulate" in GRAPH["ltd_brake_ros.cli.main"]
    assert "ltd_brake_ros.studies.runs" in GRAPH["ltd_brake_ros.cli.simulate"]
    assert cycles({"a": ["b"], "b": ["c"], "c": ["a"], "d": ["a"]}) == [["a", "b", "c"]]


def test_no_import_cycle():
    assert cycles(GRAPH) == []


@pytest.mark.parametrize("name", sorted(MODULES))
def test_ros_is_imported_at_module_level_only_by_the_ros_adapters(name):
    if under(name, "ros"):
        return
    eager = {m for m, top in imports(name) if top and m.split(".")[0] in ROS_PACKAGES}
    assert not eager, f"{name} imports {sorted(eager)} at module level"


@pytest.mark.parametrize("name", sorted(n for n in MODULES if under(n, "physics")))
def test_physics_imports_no_io_or_user_interface(name):
    banned = {"rclpy", "mcap", "matplotlib", "argparse"}
    used = {m for m, _ in imports(name) if m.split(".")[0] in banned}
    assert not used, f"{name} imports {sorted(used)}"


@pytest.mark.parametrize("name", sorted(MODULES))
def test_only_the_cli_parses_arguments_and_nothing_imports_the_adapters(name):
    targets = {m for m, _ in imports(name)}
    if not under(name, "cli"):
        assert "argparse" not in targets, f"{name} imports argparse"
        assert not {m for m in targets if under(m, "cli")}, f"{name} imports the CLI"
    if not (under(name, "ros") or under(name, "cli")):
        assert not {m for m in targets if under(m, "ros")}, f"{name} imports the ROS adapters"
