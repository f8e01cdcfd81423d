"""The package's layering (blocks, engine, workflows), read from the source: every ``import`` under
pmsmjax/ and tuning/, at module level or inside a function, parsed with :mod:`ast`
(nothing is imported but the two lazy re-export tables), as a graph of modules.

Checked: no import circle, and the one-way flow of the layers: nothing in pmsmjax imports tuning (except
the command line, inside the function that runs a subcommand), nothing imports benchmarks or tests, the
blocks (frames, machines, inverters, controllers, estimators) import nothing from the drive upwards,
controllers see of the estimators only their base, analysis never reaches jobs, presets or the command
line, and jobs never reach the command line.
"""

import ast
import importlib
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Packages whose imports are checked; imports of the other top-level folders are recognised as targets.
CHECKED = ("pmsmjax", "tuning")
TOP_LEVEL = (*CHECKED, "benchmarks", "tests")

BLOCKS = ("frames", "machines", "inverters", "controllers", "estimators")
#: What sits at or above the drive step: a block importing any of these would make a lower layer depend on
#: a higher one.
ABOVE_BLOCKS = (
    "drive", "simulate", "analysis", "recorded", "jobs", "presets", "assemble", "io", "plotting", "cli",
)  # fmt: skip
#: The estimators' modules a controller may import: the interface, not an observer.
ESTIMATOR_INTERFACE = ("pmsmjax.estimators.base",)
#: Modules that may import by name at run time (``importlib.import_module``), which this graph cannot see:
#: the command line's table of subcommands (its own modules), the registry of methods (its factories,
#: checked by test_the_registry_names_factories_of_blocks_and_presets) and the lazy re-export helper (the
#: packages' ``_LAZY`` tables it imports from are read above).
DYNAMIC_IMPORTERS = ("pmsmjax.cli", "pmsmjax.spec.registry", "pmsmjax._lazy")


@dataclass(frozen=True)
class Edge:
    source: str
    target: str
    line: int
    in_function: bool

    def __str__(self):
        where = " (inside a function)" if self.in_function else ""
        return f"{self.source} -> {self.target}  [{path_of(self.source)}:{self.line}]{where}"


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def path_of(module: str) -> str:
    return MODULES[module].relative_to(ROOT).as_posix()


MODULES = {module_name(path): path for top in TOP_LEVEL for path in sorted((ROOT / top).rglob("*.py"))}


def layer(module: str) -> str | None:
    """``pmsmjax.estimators.smo`` -> ``estimators``; ``pmsmjax.drive`` -> ``drive``; else None."""
    parts = module.split(".")
    return parts[1] if parts[0] == "pmsmjax" and len(parts) > 1 else None


def lazy_tables() -> dict[str, dict[str, str]]:
    """``{package: {name: module}}`` of the packages that re-export names lazily through a ``_LAZY`` table
    (PEP 562 ``__getattr__``): ``from pmsmjax import Profile`` depends on ``pmsmjax.scenarios``. Importing
    those packages loads no JAX (the command line relies on it)."""
    tables = {}
    for module, path in MODULES.items():
        if path.name != "__init__.py" or module.split(".")[0] not in CHECKED:
            continue
        tree = ast.parse(path.read_text(), str(path))
        assigned = {
            t.id
            for node in tree.body
            if isinstance(node, ast.Assign)
            for t in node.targets
            if isinstance(t, ast.Name)
        }
        if "_LAZY" in assigned:
            table = importlib.import_module(module)._LAZY
            tables[module] = {
                name: f"pmsmjax.{sub[2:]}" if sub.startswith("..") else f"{module}.{sub}"
                for name, (sub, _) in table.items()
            }
    return tables


LAZY = lazy_tables()


def resolve(name: str) -> str | None:
    """The project module an imported dotted name runs (the longest known prefix); None outside it."""
    parts = name.split(".")
    while parts:
        if ".".join(parts) in MODULES:
            return ".".join(parts)
        parts.pop()
    return None


def imports_of(module: str) -> list[Edge]:
    path = MODULES[module]
    tree = ast.parse(path.read_text(), str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    edges = []

    def visit(node, in_function):
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            if isinstance(child, ast.Import):
                targets = [resolve(alias.name) for alias in child.names]
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    anchor = package.split(".")[: len(package.split(".")) - (child.level - 1)]
                    base = ".".join([*anchor, base] if base else anchor)
                targets = []
                for alias in child.names:
                    full = f"{base}.{alias.name}"
                    if full in MODULES:
                        targets.append(full)
                    elif alias.name in LAZY.get(base, {}):
                        targets.append(LAZY[base][alias.name])
                    else:
                        targets.append(resolve(base))
            else:
                visit(child, inner)
                continue
            edges.extend(Edge(module, t, child.lineno, inner) for t in dict.fromkeys(targets) if t)

    visit(tree, False)
    return edges


EDGES = [edge for module in MODULES if module.split(".")[0] in CHECKED for edge in imports_of(module)]


def find_cycles(edges: list[Edge]) -> list[list[Edge]]:
    """One import circle (its edges in order) for each group of modules that import each other (each
    strongly connected component with more than one module, by Tarjan's algorithm)."""
    graph = {}
    for edge in edges:
        if edge.target != edge.source:
            graph.setdefault(edge.source, {}).setdefault(edge.target, edge)
    index, low, stack, on_stack, groups = {}, {}, [], set(), []

    def connect(module):
        index[module] = low[module] = len(index)
        stack.append(module)
        on_stack.add(module)
        for target in graph.get(module, {}):
            if target not in index:
                connect(target)
                low[module] = min(low[module], low[target])
            elif target in on_stack:
                low[module] = min(low[module], index[target])
        if low[module] == index[module]:
            group = set()
            while module not in group:
                member = stack.pop()
                on_stack.discard(member)
                group.add(member)
            if len(group) > 1:
                groups.append(group)

    for module in sorted(graph):
        if module not in index:
            connect(module)
    return [circle_in(graph, group) for group in groups]


def circle_in(graph, group: set[str]) -> list[Edge]:
    """A shortest circle through the first module of ``group`` (breadth-first inside the group)."""
    start = min(group)
    paths = {start: []}
    frontier = [start]
    while frontier:
        following = []
        for module in frontier:
            for target, edge in graph.get(module, {}).items():
                if target == start:
                    return [*paths[module], edge]
                if target in group and target not in paths:
                    paths[target] = [*paths[module], edge]
                    following.append(target)
        frontier = following
    raise AssertionError(f"no circle through {start}")


def violations(rule) -> list[str]:
    return [str(edge) for edge in EDGES if rule(edge)]


# --- the checks ---------------------------------------------------------------------------------------
def test_the_graph_is_read():
    """The parser sees what it must: the engine, each layer, lazy re-exports and imports in functions."""
    targets = {(e.source, e.target) for e in EDGES}
    assert ("pmsmjax.simulate", "pmsmjax.drive") in targets
    assert ("pmsmjax.presets.three_phase", "pmsmjax.presets.book_constants") in targets
    assert any(e.target == "pmsmjax.scenarios" and e.source.startswith("tuning.") for e in EDGES)
    assert any(e.in_function and e.source.startswith("pmsmjax.cli.") for e in EDGES)
    assert {layer(m) for m in MODULES} >= {*BLOCKS, *ABOVE_BLOCKS, "signals", "spec"}


def test_every_import_is_visible_to_this_graph():
    """A module imported by a computed name (``importlib.import_module``, ``__import__``) would hide an
    edge from every check here: only the lazy tables and the command line's subcommand table do it."""
    hidden = []
    for module in MODULES:
        if module.split(".")[0] not in CHECKED or module in LAZY or module in DYNAMIC_IMPORTERS:
            continue
        for node in ast.walk(ast.parse(MODULES[module].read_text())):
            if isinstance(node, ast.Call):
                name = getattr(node.func, "attr", getattr(node.func, "id", None))
                if name in ("import_module", "__import__"):
                    hidden.append(f"{path_of(module)}:{node.lineno}")
    assert not hidden


def test_no_import_circle():
    circles = find_cycles(EDGES)
    assert not circles, "import circles:\n" + "\n".join(
        "  " + "\n    ".join(map(str, circle)) for circle in circles
    )


def test_find_cycles_reports_every_circle_including_function_level_imports():
    edges = [
        Edge("a", "b", 1, False),
        Edge("b", "c", 2, True),
        Edge("c", "a", 3, False),
        Edge("c", "d", 4, False),
        Edge("d", "e", 5, False),
        Edge("e", "d", 6, True),
    ]
    circles = sorted([e.source for e in circle] for circle in find_cycles(edges))
    assert circles == [["a", "b", "c"], ["d", "e"]]
    assert find_cycles([e for e in edges if e.line not in (3, 6)]) == []


def test_pmsmjax_imports_tuning_only_from_a_command_when_it_runs():
    assert not violations(
        lambda e: (
            e.source.startswith("pmsmjax")
            and e.target.startswith("tuning")
            and not (layer(e.source) == "cli" and e.in_function)
        )
    )


def test_nothing_imports_benchmarks_or_tests():
    assert not violations(lambda e: e.target.split(".")[0] in ("benchmarks", "tests"))


def test_blocks_import_nothing_from_the_drive_upwards():
    assert not violations(lambda e: layer(e.source) in BLOCKS and layer(e.target) in ABOVE_BLOCKS)


def test_controllers_see_only_the_estimator_interface():
    assert not violations(
        lambda e: (
            layer(e.source) == "controllers"
            and layer(e.target) == "estimators"
            and e.target not in ESTIMATOR_INTERFACE
        )
    )


def test_analysis_reaches_neither_jobs_presets_nor_the_command_line():
    assert not violations(
        lambda e: layer(e.source) == "analysis" and layer(e.target) in ("recorded", "jobs", "presets", "cli")
    )


def test_jobs_do_not_reach_the_command_line():
    assert not violations(lambda e: layer(e.source) in ("jobs", "recorded") and layer(e.target) == "cli")


def test_the_registry_names_factories_of_blocks_and_presets():
    """The registry imports its factories by name: each is a module of the blocks or the presets, which the
    assembler may import (never the assembler, a job or the command line)."""
    from pmsmjax.spec.registry import REGISTRY

    modules = {m.factory.partition(":")[0] for m in REGISTRY if m.factory}
    assert modules and all(m in MODULES and layer(m) in (*BLOCKS, "presets") for m in modules)


def test_io_imports_nothing_above_the_spec():
    """Files are read and written in io/: it may hand what it read to the spec (its checks, derivations and
    errors) and build the flux-map grid a map file holds (plain arrays), never a block, the drive, the
    assembler, the jobs or the command line."""
    allowed = ("io", "spec")
    assert not violations(
        lambda e: (
            layer(e.source) == "io"
            and layer(e.target) is not None
            and layer(e.target) not in allowed
            and e.target != "pmsmjax.machines.flux_map"
        )
    )


def test_the_spec_loads_no_jax():
    """The spec (and io, which hands it the files) import nothing that imports JAX at module level: every
    command checks a drive before JAX starts."""
    code = (
        "import sys; from pmsmjax.io.drive_files import drive_spec; drive_spec('saturated-ipm'); "
        "drive_spec('book'); print(sorted(m for m in ('jax', 'equinox', 'scipy') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_the_command_line_imports_no_physics():
    """A command parses flags into a spec, calls a job and writes its result: the physics (blocks, engine,
    assembler, analysis) stays below the jobs."""
    physics = (
        *BLOCKS,
        "drive",
        "simulate",
        "signals",
        "trace",
        "scenarios",
        "assemble",
        "analysis",
        "recorded",
    )
    assert not violations(lambda e: layer(e.source) == "cli" and layer(e.target) in physics)
