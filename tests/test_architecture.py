"""The package's import graph: no cycles, and data flowing one way.

Every module's imports are read from its source (:mod:`ast`), the lazy ones inside
functions included, and checked against :data:`LAYERS`, the allowed layering written as
data: path and geometry -> planning -> interpolators -> loop -> metrics -> plots, report
and export -> studies -> command line. A module may import its own layer and the layers
its entry names; importing anything else fails here, naming the import and its line.

The one sanctioned exception is :data:`DELEGATIONS`: a result object's convenience method
that hands itself to a stage above (``Trace.metrics()`` -> :mod:`nurbsmotion.metrics`,
``Trace.plot()`` -> :mod:`nurbsmotion.plots`), as python-control's
``TimeResponseData.plot`` does. Such an import must stay inside the method, never at the
top of the module.

A new module must be placed in a layer here (the test names it otherwise): that is the
moment to decide where it sits.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = "nurbsmotion"

LAYERS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    # layer: (its modules, relative to the package; the lower layers it may import)
    "base": (("errors", "limits", "_runtime", "_runtime.io", "_kernels", "_runtime.jit_cache",
              "_runtime.memory", "_runtime.lazy", "_runtime.forked"), ()),
    "geometry": (("nurbs", "geometry", "joining", "feed", "chords"), ("base",)),
    "paths": (("paths", "paths.files", "paths.dxf", "paths.gcode", "paths.gcode.ngc", "paths.gcode.program",
               "paths.gcode.codes", "paths.gcode.reader", "paths.gcode.frames", "paths.gcode.curves",
               "paths.gcode.cycles", "paths.gcode.bulk", "paths.gcode.writer", "paths.gcode.compensation",
               "paths.gcode.first_part",
               "paths.ngc",
               "paths.pieces", "paths.random_paths"), ("base", "geometry")),
    # The servo side knows nothing of curves: machine does not import geometry.
    "machine": (("control", "control.step", "servo", "servo.step", "plant", "plant.two_mass", "plant.friction", "plant.stage",
                 "plant.step", "plant.sensor", "plant.linear", "machine", "random_machines"),
                ("base",)),
    # A machine from its own log (the fit's model is the plant of section 11, written for
    # the fit): it knows machines, nothing of paths.
    "identification": (("identify", "identify.log", "identify.identification",
                        "identify.excite", "identify.fit", "identify.model"),
                       ("base", "machine")),
    # Where a path meets a machine: units (a path's lengths and feeds in the machine's
    # pulses) and the drive-limited speed along the path.
    "planning": (("units", "planning", "phase_plane"), ("base", "geometry", "machine")),
    "interpolators": (("stepping", "motion_plan", "interpolators", "interpolators.base",
                       "interpolators.taylor", "interpolators.paper",
                       "interpolators.planned", "interpolators.planned.plan",
                       "interpolators.planned.blend", "interpolators.planned.inverse",
                       "interpolators.planned.landing", "interpolators.planned.shorten",
                       "interpolators.planned.identify", "interpolators.planned.governor",
                       "interpolators.planned.guards", "interpolators.planned.step",
                       "interpolators.planned.disturbance",
                       "interpolators.planned.shaper", "interpolators.planned.mode_law",
                       "interpolators.planned.rest_observer",
                       "interpolators.planned.interpolator", "interpolators.replay"),
                      ("base", "geometry", "machine", "planning")),
    "loop": (("loop", "loop.trace", "loop.closed_loop", "loop.budget", "loop.sink"),
             ("base", "geometry", "machine", "planning", "interpolators")),
    "metrics": (("metrics",),
                ("base", "geometry", "machine", "planning", "interpolators", "loop")),
    "output": (("plots", "plots._canvas", "plots.events", "plots.figures", "report",
                "report.trace_file", "report.export", "export", "identify.plot"),
               ("base", "geometry", "paths", "machine", "identification", "planning",
                "interpolators", "loop", "metrics")),
    # One run, end to end (Job -> RunResult): the loop, the metrics and the summary.
    "job": (("job",),
            ("base", "geometry", "machine", "planning", "interpolators", "loop", "metrics",
             "output")),
    # study.run_input: what a run of a named path reads (the contour and its feed), shared
    # by the CLI and a study's cases; run_input, experiments and campaign are the old
    # import paths, re-exporting the study package's names.
    "study": (("study", "study.spec", "study.case", "study.dataset", "study.execute",
               "study.run", "study.digest", "study.reproduce", "study.run_input",
               "run_input", "experiments", "campaign"),
              ("base", "geometry", "paths", "machine", "planning", "interpolators", "loop",
               "metrics", "output", "job")),
    "cli": (("cli", "cli.__main__", "cli.parser", "cli.commands", "cli.console", "__main__",
             "_runtime.precompile"),
            ("base", "geometry", "paths", "machine", "identification", "planning", "interpolators", "loop",
             "metrics", "output", "job", "study")),
    # The package's façade loads its names on first use (PEP 562), from any stage.
    "facade": (("",), ("base", "geometry", "paths", "machine", "identification", "planning", "interpolators",
                       "loop", "metrics", "output", "job", "study", "cli")),
}
"""The allowed layering, lowest first. Within a layer any import is allowed (the cycle
check still applies)."""

DELEGATIONS = {
    ("identify.identification", "identify.plot"): "Identification.plot()",
    ("loop.trace", "metrics"): "Trace.metrics() / SetpointSeries.feed_fluctuation()",
    ("loop.trace", "plots"): "Trace.plot() / SetpointSeries.plot()",
}
"""(importer, imported) imports against the flow that are allowed inside a function:
a result's method handing itself to the stage that owns that work."""


@dataclass(frozen=True)
class Edge:
    """One import of a package module by another."""

    importer: str
    imported: str
    line: int
    lazy: bool  # inside a function (run when called, not when the module loads)

    def __str__(self):
        where = "inside a function" if self.lazy else "at module level"
        return (f"{_file(self.importer)}:{self.line} imports {_dotted(self.imported)} "
                f"({where})")


def _dotted(module: str) -> str:
    return PACKAGE + ("." + module if module else "")


def _file(module: str) -> str:
    return str(_path_of(module).relative_to(SRC.parent))


def _path_of(module: str) -> Path:
    base = SRC / PACKAGE / Path(*module.split(".")) if module else SRC / PACKAGE
    return base / "__init__.py" if base.is_dir() else base.with_suffix(".py")


def package_modules() -> list[str]:
    """Every module of the package, relative to it ("" for the package itself)."""
    found = []
    for path in sorted((SRC / PACKAGE).rglob("*.py")):
        parts = list(path.relative_to(SRC / PACKAGE).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found.append(".".join(parts))
    return found


def _lazy_names(tree: ast.Module) -> set[str]:
    """Submodule names a package's ``_LAZY`` table loads with ``import_module`` (PEP 562):
    the string values assigned to ``_LAZY`` or passed to ``_LAZY.update``."""
    names = set()
    for node in ast.walk(tree):
        value = None
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == "_LAZY" for t in node.targets):
            value = node.value
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and isinstance(node.func.value, ast.Name) and node.func.value.id == "_LAZY"
              and node.func.attr == "update" and node.args):
            value = node.args[0]
        if isinstance(value, ast.Dict):
            names |= {v.value for v in value.values if isinstance(v, ast.Constant)}
        elif isinstance(value, ast.DictComp) and isinstance(value.value, ast.Constant):
            names.add(value.value.value)
    return names


def _walk(node: ast.AST, lazy: bool = False):
    """Every import statement under ``node``, with whether it sits inside a function."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, (ast.Import, ast.ImportFrom)):
            yield child, lazy
        inner = lazy or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef,
                                           ast.Lambda))
        yield from _walk(child, inner)


def imports_of(module: str, modules: set[str]) -> list[Edge]:
    """The package modules ``module`` imports, read from its source."""
    is_package = _path_of(module).name == "__init__.py"
    tree = ast.parse(_path_of(module).read_text(encoding="utf-8"))
    own = module.split(".") if module else []
    ancestors = {".".join(own[:k]) for k in range(len(own) + (1 if is_package else 0))}
    edges = []

    def add(target: str, node: ast.AST, lazy: bool):
        if target != module:
            edges.append(Edge(module, target, node.lineno, lazy))

    for node, lazy in _walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name == PACKAGE or alias.name.startswith(PACKAGE + "."):
                    add(alias.name[len(PACKAGE) + 1:], node, lazy)
            continue
        if node.level:
            base = own if is_package else own[:-1]
            base = base[:len(base) - (node.level - 1)]
            target = ".".join(base + ([node.module] if node.module else []))
        elif node.module and (node.module == PACKAGE or node.module.startswith(PACKAGE + ".")):
            target = node.module[len(PACKAGE) + 1:]
        else:
            continue
        for alias in node.names:
            sub = f"{target}.{alias.name}" if target else alias.name
            if sub in modules:
                add(sub, node, lazy)
            elif target not in ancestors:
                # A name from an ancestor package (``from . import __version__``) is not
                # an edge: Python runs every ancestor's __init__ before the importer.
                add(target, node, lazy)
    if is_package:
        prefix = module + "." if module else ""
        for name in _lazy_names(tree):
            if prefix + name in modules:
                edges.append(Edge(module, prefix + name, 0, True))
    return list(dict.fromkeys(edges))  # one edge per line, however many names it imports


def layer_of() -> dict[str, str]:
    return {m: layer for layer, (members, _) in LAYERS.items() for m in members}


@pytest.fixture(scope="module")
def graph() -> dict[str, list[Edge]]:
    modules = package_modules()
    return {m: imports_of(m, set(modules)) for m in modules}


def test_layers_form_one_way_chain():
    """Each layer may import only layers listed before it: the allowed layering itself
    has no way back up."""
    names = list(LAYERS)
    for k, (layer, (_, below)) in enumerate(LAYERS.items()):
        for other in below:
            assert other in names[:k], f"layer {layer!r} may import {other!r}, not below it"
    members = [m for members, _ in LAYERS.values() for m in members]
    assert len(members) == len(set(members)), "a module is in two layers"
    assert all(a in layer_of() and b in layer_of() for a, b in DELEGATIONS)


def test_every_module_has_a_layer(graph):
    unplaced = sorted(_dotted(m) for m in graph if m not in layer_of())
    assert not unplaced, (f"modules in no layer of tests/test_architecture.py LAYERS: "
                          f"{unplaced}; decide where each sits in the flow")


def test_imports_follow_the_layers(graph):
    layer = layer_of()
    wrong = []
    for edges in graph.values():
        for e in edges:
            if e.importer not in layer or e.imported not in layer:
                continue  # reported by test_every_module_has_a_layer
            own, other = layer[e.importer], layer[e.imported]
            if own == other or other in LAYERS[own][1]:
                continue
            if (e.importer, e.imported) in DELEGATIONS and e.lazy:
                continue
            wrong.append(f"{e}: layer {own!r} may not import layer {other!r}")
    assert not wrong, "imports against the flow:\n" + "\n".join(wrong)


def test_delegations_stay_lazy(graph):
    """The sanctioned upward imports happen inside the method, never when the module
    loads (importing the loop must not import the plots, nor matplotlib)."""
    eager = [str(e) for edges in graph.values() for e in edges
             if (e.importer, e.imported) in DELEGATIONS and not e.lazy]
    assert not eager, "\n".join(eager)


def test_no_import_cycles(graph):
    """No strongly connected component of more than one module, lazy imports included
    (Tarjan's algorithm)."""
    targets = {m: sorted({e.imported for e in edges if e.imported in graph})
               for m, edges in graph.items()}
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def connect(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in targets[v]:
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
                cycles.append(sorted(_dotted(m) for m in component))

    for v in targets:
        if v not in index:
            connect(v)
    assert not cycles, f"import cycles: {cycles}"


def test_the_reader_sees_lazy_and_relative_imports():
    """The scan finds what it must: a lazy delegation, a relative import two levels up,
    the façade's PEP 562 table, and no edge for an ancestor's ``__version__``."""
    modules = set(package_modules())
    trace = {(e.imported, e.lazy) for e in imports_of("loop.trace", modules)}
    assert ("plots", True) in trace and ("metrics", True) in trace
    loop = {(e.imported, e.lazy) for e in imports_of("loop", modules)}
    assert ("loop.closed_loop", False) in loop and ("stepping", False) in loop
    planned = {e.imported for e in imports_of("interpolators.planned.interpolator", modules)}
    assert {"stepping", "interpolators.planned.plan", "interpolators.base"} <= planned
    facade = {e.imported for e in imports_of("", modules)}
    assert {"nurbs", "joining", "paths", "errors"} <= facade
    paths = {e.imported for e in imports_of("paths", modules)}
    assert {"paths.files", "paths.dxf", "paths.gcode"} <= paths
    assert "" not in {e.imported for e in imports_of("cli", modules)}


def test_a_cycle_would_be_found():
    """The cycle finder on a made-up graph (guards the guard)."""
    fake = {"a": [Edge("a", "b", 1, False)], "b": [Edge("b", "c", 1, True)],
            "c": [Edge("c", "a", 1, True)], "d": []}
    with pytest.raises(AssertionError, match="import cycles"):
        test_no_import_cycles(fake)
