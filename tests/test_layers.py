"""The layers of the code base, read from the source with :mod:`ast` (nothing is imported).

The arrows: service -> computations (``pipeflow.computations``: what runs a request) ->
schema (``pipeflow.schema``: the pydantic models) -> library, never back.  The rules:

1. no import circle among the modules of ``pipeflow``, ``service``, ``pipeflow_client`` and
   ``pipeflow_cli``
   (every import counts, deferred ones inside functions too: a circle broken only by
   deferring an import is still a circle of responsibilities, and so is one broken only by
   putting an import under ``if TYPE_CHECKING:``, which counts here and nowhere else);
2. the library (``pipeflow``) imports nothing of the service, of the client, nor of the web
   and cluster stack (fastapi, starlette, uvicorn, distributed, sqlalchemy);
3. the engine (``service.engine``) imports nothing of the HTTP layer (``service.http``, the
   routes and what builds answers, fastapi, starlette): it returns plain outcomes and
   neutral error records, which only the HTTP layer turns into problem documents;
4. the numerical library (``pipeflow`` outside ``pipeflow.schema``,
   ``pipeflow.computations`` and the presentation layer ``pipeflow.io``) imports nothing of
   the schema (``pipeflow.schema``) nor of the computations, deferred imports included: it
   returns dataclasses, and the computations build the documents from them
   (``pipeflow.computations.documents``);
5. the schema imports nothing of the computations (the models are the contract; what runs
   them sits one floor up);
6. size: no module of ``pipeflow`` or ``service`` over :data:`MAX_MODULE_LINES` lines, no
   class over :data:`MAX_CLASS_LINES` lines.
7. the engine by role: its parts (cluster, lane, drive, dispatcher, watches, monitor)
   import neither each other nor the runner, which owns and wires them with callbacks;
   its floor (flight, outcome, lifecycle) imports none of the parts; ``lifecycle`` (the job
   and task states) imports nothing of the project, and it is all the store imports of
   the engine.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("pipeflow", "service", "pipeflow_client", "pipeflow_cli")


#: what the library must not import (rule 2)
LIBRARY_FORBIDDEN = (
    "service",
    "pipeflow_client",
    "fastapi",
    "starlette",
    "uvicorn",
    "distributed",
    "sqlalchemy",
)

#: the HTTP layer, which the engine must not import (rule 3)
HTTP_LAYER = (
    "service.http",
    "service.routes",
    "service.orchestration",
    "service.main",
    "service.deps",
    "fastapi",
    "starlette",
)


#: the contract, which the numerical library must not import (rule 4)
SCHEMA = "pipeflow.schema"
#: what runs a request, one floor above the contract (rules 4 and 5)
COMPUTATIONS = "pipeflow.computations"
#: the parts of ``pipeflow`` that may import the contract and the computations: themselves
#: and the presentation layer (a notebook view turns a local result into its document)
SCHEMA_USERS = (SCHEMA, COMPUTATIONS, "pipeflow.io")

#: the size rules (rule 6)
MAX_MODULE_LINES = 800
MAX_CLASS_LINES = 400


#: the engine's parts (rule 7): each is handed what it needs by the runner
ENGINE_PARTS = tuple(
    f"service.engine.{m}" for m in ("cluster", "lane", "drive", "dispatcher", "watches", "monitor")
)
#: the floor below them, and the one module of it the store may import
ENGINE_FLOOR = tuple(f"service.engine.{m}" for m in ("flight", "outcome", "lifecycle"))
LIFECYCLE = "service.engine.lifecycle"
RUNNER = "service.engine.runner"


@dataclass(frozen=True)
class Import:
    module: str  # the importing module
    target: str  # the imported module (a submodule when ``from pkg import submodule``)
    line: int
    deferred: bool  # inside a function
    type_only: bool = False  # under ``if TYPE_CHECKING:``


def module_name(root: Path, path: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def source_files(root: Path, packages: Iterable[str]) -> Iterator[Path]:
    for package in packages:
        top = root / package
        if top.is_dir():
            yield from sorted(p for p in top.rglob("*.py") if "migrations" not in p.parts[:-1])


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def imports_of(root: Path, path: Path, modules: set[str]) -> list[Import]:
    """Every import of the file at ``path`` (``modules``: the known modules, to tell a
    submodule from a name in ``from package import name``)."""
    name = module_name(root, path)
    is_package = path.name == "__init__.py"
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found: list[Import] = []

    def visit(node: ast.AST, deferred: bool, type_only: bool = False) -> None:
        if isinstance(node, ast.If) and _type_checking(node):
            for child in node.body:
                visit(child, deferred, True)
            for child in node.orelse:
                visit(child, deferred, type_only)
            return
        if isinstance(node, ast.Import):
            for alias in node.names:
                found.append(Import(name, alias.name, node.lineno, deferred, type_only))
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = name.split(".")
                keep = len(parts) - node.level + (1 if is_package else 0)
                base = ".".join(parts[:keep] + ([base] if base else []))
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                target = sub if sub in modules else base
                found.append(Import(name, target, node.lineno, deferred, type_only))
        inner = deferred or isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda)
        for child in ast.iter_child_nodes(node):
            visit(child, inner, type_only)

    visit(tree, False)
    return found


def all_imports(root: Path, packages: Iterable[str] = PACKAGES) -> list[Import]:
    files = list(source_files(root, packages))
    modules = {module_name(root, p) for p in files}
    return [imp for p in files for imp in imports_of(root, p, modules)]


def within(target: str, prefixes: Iterable[str]) -> bool:
    return any(target == p or target.startswith(p + ".") for p in prefixes)


def circles(imports: Iterable[Import]) -> list[frozenset[str]]:
    """The import circles: strongly connected groups of two or more modules (Tarjan)."""
    graph: dict[str, set[str]] = {}
    for imp in imports:
        graph.setdefault(imp.module, set())
    for imp in imports:
        if imp.target in graph and imp.target != imp.module:
            graph[imp.module].add(imp.target)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[frozenset[str]] = []
    counter = [0]

    def connect(v: str) -> None:  # recursion depth: the longest import chain (small)
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.add(w)
                if w == v:
                    break
            if len(group) > 1:
                found.append(frozenset(group))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return found


def violations(
    imports: Iterable[Import],
    layer: str,
    forbidden: Iterable[str],
    exempt: Iterable[str] = (),
) -> list[str]:
    """``module:line imports target`` for each import of ``layer`` (but of its parts
    ``exempt``) that is ``forbidden``"""
    forbidden, exempt = tuple(forbidden), tuple(exempt)
    return [
        f"{imp.module}:{imp.line} imports {imp.target}"
        for imp in imports
        if within(imp.module, [layer])
        and not within(imp.module, exempt)
        and within(imp.target, forbidden)
    ]


def engine_violations(imports: Iterable[Import]) -> list[str]:
    """``module:line imports target`` for each import that breaks rule 7."""
    bad = []
    for imp in imports:
        upward = (
            within(imp.module, ENGINE_PARTS)
            and imp.target != imp.module
            and within(imp.target, (*ENGINE_PARTS, RUNNER))
        )
        upward |= within(imp.module, ENGINE_FLOOR) and within(imp.target, (*ENGINE_PARTS, RUNNER))
        upward |= imp.module == LIFECYCLE and within(imp.target, PACKAGES)
        upward |= (
            within(imp.module, ["service.store"])
            and within(imp.target, ["service.engine"])
            and imp.target != LIFECYCLE
        )
        if upward:
            bad.append(f"{imp.module}:{imp.line} imports {imp.target}")
    return bad


# -- the rules, on the tree ----------------------------------------------------------------


@pytest.fixture(scope="module")
def every_import() -> list[Import]:
    return all_imports(ROOT)


@pytest.fixture(scope="module")
def tree_imports(every_import: list[Import]) -> list[Import]:
    """The imports the layer rules read: those that run (not the type checker's alone)."""
    return [imp for imp in every_import if not imp.type_only]


def test_no_import_circles(every_import: list[Import]) -> None:
    found = circles(every_import)
    assert not found, "import circles: " + "; ".join(" <-> ".join(sorted(c)) for c in found)


def test_library_imports_no_service_client_or_web_stack(tree_imports: list[Import]) -> None:
    bad = violations(tree_imports, "pipeflow", LIBRARY_FORBIDDEN)
    assert not bad, "the library imports the service, the client or the web stack:\n" + "\n".join(
        bad
    )


def test_library_imports_no_schema(tree_imports: list[Import]) -> None:
    """The numerical library returns dataclasses; the computations build the response
    documents from them (``pipeflow.computations.documents``), never the other way round."""
    bad = violations(tree_imports, "pipeflow", [SCHEMA, COMPUTATIONS], exempt=SCHEMA_USERS)
    assert not bad, "the library imports the schema or the computations:\n" + "\n".join(bad)


def test_schema_imports_no_computations(tree_imports: list[Import]) -> None:
    """The models are the contract; what runs them (``pipeflow.computations``) imports the
    schema, never the other way round."""
    bad = violations(tree_imports, SCHEMA, [COMPUTATIONS])
    assert not bad, "the schema imports the computations:\n" + "\n".join(bad)


def test_client_and_command_line_stay_front_ends(tree_imports: list[Import]) -> None:
    """The client speaks HTTP to the service and never imports it; nothing imports the
    command line, which sits on top of the library and the client."""
    bad = violations(tree_imports, "pipeflow_client", ("service", "pipeflow_cli"))
    bad += [
        f"{imp.module}:{imp.line} imports {imp.target}"
        for imp in tree_imports
        if within(imp.target, ["pipeflow_cli"]) and not within(imp.module, ["pipeflow_cli"])
    ]
    assert not bad, "a front end is imported the wrong way:\n" + "\n".join(bad)


def test_engine_imports_no_http_layer(tree_imports: list[Import]) -> None:
    bad = violations(tree_imports, "service.engine", HTTP_LAYER)
    assert not bad, "the engine imports the HTTP layer:\n" + "\n".join(bad)


def test_engine_parts_are_wired_by_the_runner(tree_imports: list[Import]) -> None:
    """The engine's parts talk through the callbacks the runner hands them, never by
    importing each other; the floor and the store import none of them."""
    bad = engine_violations(tree_imports)
    assert not bad, "the engine's parts import each other (or upwards):\n" + "\n".join(bad)
    imported = {imp.target for imp in tree_imports if imp.module == RUNNER}
    assert set(ENGINE_PARTS) <= imported  # the rule sees the parts: they exist by these names


def test_the_tree_is_read(tree_imports: list[Import]) -> None:
    """The rules above see the code base (a wrong root would make them pass vacuously)."""
    modules = {imp.module for imp in tree_imports}
    assert {
        "pipeflow.computations.study_runner",
        "pipeflow.schema.study",
        "service.engine.task",
        "service.http.problems",
    } <= modules
    assert "pipeflow_cli.cli" in modules
    assert any(imp.target == "pipeflow.errors" for imp in tree_imports)
    assert any(
        imp.module == "pipeflow.computations.documents" and imp.target == "pipeflow.simulation"
        for imp in tree_imports
    )


# -- the rules catch violations (a synthetic tree) -----------------------------------------


def _write(root: Path, files: dict[str, str]) -> None:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")


def test_rules_catch_violations_in_a_synthetic_tree(tmp_path: Path) -> None:
    _write(
        tmp_path,
        {
            "pipeflow/__init__.py": "",
            "pipeflow/a.py": "from pipeflow import b\n",
            "pipeflow/b.py": "def f():\n    from pipeflow.a import x  # deferred: still a circle\n",
            "pipeflow/c.py": "import sqlalchemy\nfrom service.store import Store\n",
            "pipeflow/d.py": (
                "from typing import TYPE_CHECKING\n"
                "if TYPE_CHECKING:\n    from service import engine  # typing only: allowed\n"
            ),
            "pipeflow/e.py": "def serve():\n    import fastapi  # deferred\n",
            "pipeflow/f.py": "def to_dict():\n    from pipeflow.schema import results\n",
            "pipeflow/g.py": "import pipeflow.schema.results\nfrom pipeflow import schema\n",
            "pipeflow/schema/__init__.py": "",
            "pipeflow/schema/results.py": "",
            "pipeflow/schema/documents.py": "from pipeflow import a\nfrom . import results\n",
            "pipeflow/io/__init__.py": "",
            "pipeflow/io/notebook.py": (
                "def view():\n    from pipeflow.computations import documents\n"
            ),
            "pipeflow/h.py": "from pipeflow.computations import registry\n",
            "pipeflow/schema/stability.py": "from pipeflow.computations import documents\n",
            "pipeflow/computations/__init__.py": "",
            "pipeflow/computations/registry.py": "from pipeflow.schema import results\n",
            "pipeflow/computations/documents.py": "from pipeflow import a\n",
            "service/__init__.py": "",
            "service/http/__init__.py": "",
            "service/http/problems.py": "from service.engine import task\n",
            "service/engine/__init__.py": "",
            "service/engine/task.py": "from ..http.problems import problem\n",
            "service/engine/ok.py": "from pipeflow import a\n",
            # a circle through a type-checking import is a circle
            "pipeflow/t1.py": "from pipeflow import t2\n",
            "pipeflow/t2.py": (
                "from typing import TYPE_CHECKING\n"
                "if TYPE_CHECKING:\n    from pipeflow.t1 import T\n"
            ),
        },
    )
    every = all_imports(tmp_path, ("pipeflow", "service"))
    assert set(circles(every)) == {
        frozenset({"pipeflow.a", "pipeflow.b"}),
        frozenset({"service.engine.task", "service.http.problems"}),
        frozenset({"pipeflow.t1", "pipeflow.t2"}),
    }
    imports = [imp for imp in every if not imp.type_only]  # the layer rules' imports
    assert violations(imports, "pipeflow", LIBRARY_FORBIDDEN) == [
        "pipeflow.c:1 imports sqlalchemy",
        "pipeflow.c:2 imports service.store",
        "pipeflow.e:2 imports fastapi",
    ]
    assert violations(imports, "pipeflow", [SCHEMA, COMPUTATIONS], exempt=SCHEMA_USERS) == [
        "pipeflow.f:2 imports pipeflow.schema.results",
        "pipeflow.g:1 imports pipeflow.schema.results",
        "pipeflow.g:2 imports pipeflow.schema",
        "pipeflow.h:1 imports pipeflow.computations.registry",
    ]
    assert violations(imports, SCHEMA, [COMPUTATIONS]) == [
        "pipeflow.schema.stability:1 imports pipeflow.computations.documents"
    ]
    assert violations(imports, "service.engine", HTTP_LAYER) == [
        "service.engine.task:1 imports service.http.problems"
    ]


# -- the size rules ------------------------------------------------------------------------


def oversized(root: Path, packages: Iterable[str]) -> list[str]:
    """``path: N lines`` for each module over :data:`MAX_MODULE_LINES` lines and
    ``path:line class C: N lines`` for each class (nested ones too) over
    :data:`MAX_CLASS_LINES` lines, from its ``class`` line (or first decorator) to its last
    line (:mod:`ast` spans)."""
    found: list[str] = []
    for path in source_files(root, packages):
        text = path.read_text(encoding="utf-8")
        rel = path.relative_to(root).as_posix()
        lines = len(text.splitlines())
        if lines > MAX_MODULE_LINES:
            found.append(f"{rel}: {lines} lines")
        for node in ast.walk(ast.parse(text, filename=str(path))):
            if isinstance(node, ast.ClassDef):
                first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
                span = (node.end_lineno or node.lineno) - first + 1
                if span > MAX_CLASS_LINES:
                    found.append(f"{rel}:{node.lineno} class {node.name}: {span} lines")
    return found


def test_no_module_or_class_over_the_size_limits() -> None:
    """No module of the library or the service over 800 lines, no class over 400: a file
    that grows past them is a room doing several jobs (split it by concern)."""
    found = oversized(ROOT, ("pipeflow", "service"))
    assert not found, "over the size limits:\n" + "\n".join(found)


def test_size_rules_catch_violations_in_a_synthetic_tree(tmp_path: Path) -> None:
    body = "    x = 1\n" * MAX_CLASS_LINES
    _write(
        tmp_path,
        {
            "pipeflow/__init__.py": "",
            "pipeflow/big.py": "x = 1\n" * (MAX_MODULE_LINES + 1),
            "pipeflow/fits.py": "x = 1\n" * MAX_MODULE_LINES,
            # a class of 401 lines (its line and 400 of body); one of 400 with its decorator
            "service/__init__.py": "",
            "service/wide.py": "class Wide:\n" + body,
            "service/ok.py": "@dataclass\nclass Ok:\n" + "    x = 1\n" * (MAX_CLASS_LINES - 2),
        },
    )
    assert oversized(tmp_path, ("pipeflow", "service")) == [
        f"pipeflow/big.py: {MAX_MODULE_LINES + 1} lines",
        f"service/wide.py:1 class Wide: {MAX_CLASS_LINES + 1} lines",
    ]


def test_engine_rule_catches_violations_in_a_synthetic_tree(tmp_path: Path) -> None:
    _write(
        tmp_path,
        {
            "service/__init__.py": "",
            "service/store/__init__.py": "",
            "service/store/jobs.py": (
                "from service.engine.lifecycle import JobState  # allowed\n"
                "from service.engine import task\n"
            ),
            "service/engine/__init__.py": "",
            "service/engine/task.py": "",
            "service/engine/lifecycle.py": "import enum\nfrom service import settings\n",
            "service/engine/flight.py": "from service.engine import lifecycle, monitor\n",
            "service/engine/lane.py": "from service.engine import flight\n",  # allowed
            "service/engine/monitor.py": "def f():\n    from service.engine.lane import x\n",
            "service/engine/drive.py": "from service.engine.runner import Runner\n",
            "service/engine/runner.py": "from service.engine import drive, lane, monitor\n",
            "service/settings.py": "",
        },
    )
    assert engine_violations(all_imports(tmp_path, ("service",))) == [
        "service.engine.drive:1 imports service.engine.runner",
        "service.engine.flight:1 imports service.engine.monitor",
        "service.engine.lifecycle:2 imports service.settings",
        "service.engine.monitor:2 imports service.engine.lane",
        "service.store.jobs:2 imports service.engine.task",
    ]
