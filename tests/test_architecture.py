"""The house's rules, read from the source (ast, nothing imported): ``report/`` renders the
written files and imports nothing of the estimator, and no import circle exists among the
package's modules (imports inside functions count as much as those at the top)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "vision_cal"

#: what report/ may import besides itself and dataset/: the package root (``__version__``
#: for the provenance) and the one exception type
REPORT_MAY_IMPORT = ("vision_cal.report", "vision_cal.dataset")
REPORT_ALSO = {"vision_cal", "vision_cal.errors"}


def modules(package: Path = PACKAGE) -> dict[str, Path]:
    """Dotted name -> file of every module (a package is its ``__init__``)."""
    out = {}
    for p in package.rglob("*.py"):
        parts = list(p.relative_to(package.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def imports_of(name: str, path: Path, known: dict) -> set[str]:
    """The package modules ``name`` imports, anywhere in the file. ``from a.b import c``
    is the module ``a.b.c`` when there is one, else ``a.b``; relative imports resolved."""

    def module(dotted: str) -> str | None:
        while dotted and dotted not in known:
            dotted = dotted.rpartition(".")[0]
        return dotted or None

    here = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            out |= {module(a.name) for a in node.names if a.name.split(".")[0] == "vision_cal"}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(here[:len(here) - node.level + 1] + ([base] if base else []))
            if base.split(".")[0] != "vision_cal":
                continue
            for a in node.names:
                full = f"{base}.{a.name}"
                out.add(full if full in known else module(base))
    out.discard(None)
    out.discard(name)
    return out


def import_graph(package: Path = PACKAGE) -> dict[str, set[str]]:
    known = modules(package)
    return {name: imports_of(name, path, known) for name, path in known.items()}


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def report_violations(graph: dict[str, set[str]]) -> dict[str, list[str]]:
    return {m: sorted(bad) for m, deps in graph.items()
            if m == "vision_cal.report" or m.startswith("vision_cal.report.")
            for bad in [{d for d in deps if d not in REPORT_ALSO and not any(
                d == p or d.startswith(p + ".") for p in REPORT_MAY_IMPORT)}] if bad}


@pytest.fixture(scope="module")
def graph():
    return import_graph()


def test_report_reads_files_and_imports_nothing_of_the_estimator(graph):
    assert "vision_cal.report.html" in graph and graph["vision_cal.report.html"]
    assert report_violations(graph) == {}


def test_no_import_circle(graph):
    assert circles(graph) == []


def test_the_checks_see_what_they_guard(tmp_path):
    """A report module reaching into the estimator inside a function, and two modules
    importing each other (one of them inside a function), are both found."""
    pkg = tmp_path / "vision_cal"
    for d in ("report", "measure", "dataset"):
        (pkg / d).mkdir(parents=True)
        (pkg / d / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "report" / "plots.py").write_text(
        "from vision_cal.dataset import io\n\ndef f():\n    from ..measure import batch\n")
    (pkg / "dataset" / "io.py").write_text("")
    (pkg / "measure" / "batch.py").write_text("from vision_cal.measure.cache import get\n")
    (pkg / "measure" / "cache.py").write_text("def get():\n    from . import batch\n")
    g = import_graph(pkg)
    assert report_violations(g) == {"vision_cal.report.plots": ["vision_cal.measure.batch"]}
    assert circles(g) == [["vision_cal.measure.batch", "vision_cal.measure.cache"]]


def test_every_command_is_on_the_command_line():
    """A command whose import breaks must fail loudly, never vanish from the CLI: the
    parser holds every name ``SUBCOMMANDS`` lists, and main.py catches no import error."""
    from vision_cal.commands import main as cli

    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    assert set(cli.SUBCOMMANDS) <= set(sub.choices)
    tree = ast.parse((PACKAGE / "commands" / "main.py").read_text())
    caught = {ast.unparse(h.type) for h in ast.walk(tree)
              if isinstance(h, ast.ExceptHandler) and h.type is not None}
    assert not caught & {"ModuleNotFoundError", "ImportError"}, caught
