"""The house's layout, read from the imports (ast), so it cannot drift back.

Layers, bottom to top: ``robot_models`` (robot facts) < ``sim_bridge`` (the simulation core) <
``sim_ros`` (what the ROS side shares) < ``nodes`` (ROS nodes) and ``sim_client`` (scripts, scenarios,
CLI). Imports point down only, never in a cycle; the core knows no ROS; robots are named only where
robots are defined (``robot_models``), chosen (scenario files, benchmarks) or tested.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("robot_models", "sim_bridge", "sim_ros", "nodes", "sim_client")
SCRIPTS = ("benchmarks", "tools")  # scripts: held to the size limit, not to the layers
MAX_LINES = 500
ROBOT_NAMES = ("g1", "panda")

# package -> project packages and third-party roots it must never import
FORBIDDEN = {
    "robot_models": ("sim_bridge", "sim_ros", "nodes", "sim_client", "rclpy"),
    "sim_bridge": ("sim_ros", "nodes", "sim_client", "rclpy"),
    "sim_ros": ("nodes", "sim_client"),
    "nodes": ("sim_client",),
}


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def project_files() -> dict[str, Path]:
    return {module_name(p): p for package in PACKAGES for p in sorted((ROOT / package).rglob("*.py"))}


MODULES = project_files()


def imports_of(path: Path) -> Iterator[tuple[str, int]]:
    """Every module an import statement of ``path`` names (anywhere in it: lazy and TYPE_CHECKING ones too)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                child = f"{node.module}.{alias.name}"
                yield (child if child in MODULES else node.module), node.lineno


def graph() -> dict[str, set[str]]:
    return {name: {target for target, _ in imports_of(path) if target in MODULES} for name, path in MODULES.items()}


def find_cycle(edges: dict[str, set[str]]) -> list[str] | None:
    """One import cycle as a list of modules (first == last), or None."""
    state: dict[str, int] = {}  # 1 = on the stack, 2 = done
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for target in sorted(edges.get(node, ())):
            if state.get(target) == 1:
                return [*stack[stack.index(target):], target]
            if target not in state and (cycle := visit(target)):
                return cycle
        stack.pop()
        state[node] = 2
        return None

    for start in sorted(edges):
        if start not in state and (cycle := visit(start)):
            return cycle
    return None


def test_the_checker_finds_a_cycle() -> None:
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None


def test_every_package_is_found() -> None:
    for package in PACKAGES:
        assert package in MODULES, f"{package}/__init__.py is missing"


def test_no_import_cycle_between_project_modules() -> None:
    cycle = find_cycle(graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_layers_point_down(package: str) -> None:
    wrong = [f"{MODULES[name].relative_to(ROOT)}:{line} imports {target}"
             for name in MODULES if name == package or name.startswith(package + ".")
             for target, line in imports_of(MODULES[name])
             if target.split(".")[0] in FORBIDDEN[package]]
    assert not wrong, "\n".join(wrong)


def test_no_private_name_is_imported_from_another_module() -> None:
    files = [*MODULES.values(), *(p for d in (*SCRIPTS, "tests") for p in (ROOT / d).rglob("*.py"))]
    wrong = []
    for path in files:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in PACKAGES:
                wrong += [f"{path.relative_to(ROOT)}:{node.lineno} imports {node.module}.{a.name}"
                          for a in node.names if a.name.startswith("_") and not a.name.startswith("__")]
    assert not wrong, "\n".join(wrong)


def test_robots_are_named_only_in_robot_models() -> None:
    wrong = []
    for name, path in MODULES.items():
        if name.split(".")[0] == "robot_models":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Constant) and node.value in ROBOT_NAMES:
                wrong.append(f"{path.relative_to(ROOT)}:{node.lineno} names the robot {node.value!r}")
    assert not wrong, "use the names robot_models defines:\n" + "\n".join(wrong)


def test_no_module_over_the_size_limit() -> None:
    files = [*MODULES.values(), *(p for d in SCRIPTS for p in (ROOT / d).rglob("*.py"))]
    long = [f"{p.relative_to(ROOT)}: {n} lines" for p in files if (n := len(p.read_text().splitlines())) > MAX_LINES]
    assert not long, f"modules over {MAX_LINES} lines (split them by concept):\n" + "\n".join(long)


# Processes that hold no robot model: they import neither the physics nor the core (issue 24: a G1
# bringup's memory; a device node that imported them carried ~30 MB more than a bare rclpy node).
LIGHT_MODULES = ("nodes.devices.power", "nodes.devices.hand_sensors", "nodes.devices.head", "nodes.devices.camera",
                 "nodes.launch.bringup")


@pytest.mark.parametrize("module", LIGHT_MODULES)
def test_light_processes_import_no_physics(module: str) -> None:
    probe = f"import sys, {module}; print(' '.join(m for m in ('mujoco', 'mink', 'sim_bridge') if m in sys.modules))"
    loaded = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True, cwd=ROOT,
                            timeout=60).stdout.split()
    assert not loaded, f"importing {module} loads {', '.join(loaded)}"
