"""House rule: imports run downward (../shared/STYLE.md, "A layout that shows the architecture").

Every module under ``src/wearnav`` is parsed with :mod:`ast` (not imported) and each of its imports
of ``wearnav.*`` is collected: module level and inside functions, ``import`` and ``from ... import``,
absolute and relative, ``TYPE_CHECKING`` blocks included (a type-only import is still a
dependency between the two files). ``from wearnav.pkg import name`` counts as an import of
``wearnav.pkg.name`` where that is a module, else of ``wearnav.pkg``. Two rules:

* no import cycle between modules (the cycle is named);
* no module imports a module of a higher layer (:data:`LAYERS`; the pair is named).

The implicit import of a parent package (``import wearnav.a.b`` runs ``wearnav/a/__init__.py``)
is not counted: every module would then import the root package.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"

# The layer of each module, by the longest matching dotted prefix. Data flows importers/simulate →
# recording → preprocess → windows → models → train → evaluate → bench/report → cli, with track
# and live beside cli (live's tracker uses track, so live sits above it). A module may import
# modules of its own layer or lower ones; cycles are caught separately. Where a module's layer
# differs from its folder's, the comment says why (what it imports and who imports it today).
LAYERS: dict[str, int] = {
    # 0 foundations: errors, files, text, clocks, rotations and the pure numeric helpers; they
    # import nothing of wearnav but each other
    "wearnav.errors": 0,
    "wearnav.core": 0,  # the package of the foundations below
    "wearnav.core.fileio": 0,
    "wearnav.core.textio": 0,
    "wearnav.core.progress": 0,
    "wearnav.core.provenance": 0,  # also holds __version__ (the root package re-exports it)
    "wearnav.core.interrupts": 0,  # Ctrl-C / SIGTERM that a finalizer swallowed, raised again later
    "wearnav.core.rotations": 0,
    "wearnav.core.timeseries": 0,
    "wearnav.core.geo": 0,
    "wearnav.stats": 0,
    "wearnav.trust": 0,
    "wearnav.fixcheck": 0,
    "wearnav.trajectory": 0,
    "wearnav.metrics": 0,
    # the one activity label set and each source's mapping onto it (data only; issue 35)
    "wearnav.activity_labels": 0,
    # an exported model file's header (format, names); train.classify and track read it, and it
    # imports only errors, so it sits far below the rest of export/
    "wearnav.export.header": 0,
    # 1 the data model: one Recording, a Dataset folder of them, run and output folders
    "wearnav.recording": 1,
    "wearnav.recording.checks": 1,  # the checks Recording's parts run on construction
    "wearnav.recording.radio": 1,  # a Recording's beacons, pressure and floor plans (recording re-exports them)
    "wearnav.dataset": 1,
    "wearnav.outputs": 1,
    "wearnav.plans": 1,  # floor plans' geometry (shapely): importers place plans with it, fuse and track use it
    "wearnav.runs": 1,
    "wearnav": 1,  # the root package: re-exports Dataset, Recording ... and __version__
    # 2 sources: importers (public datasets, Sensor Logger) and the simulator write Recordings
    "wearnav.importers": 2,
    "wearnav.simulate": 2,
    # 3 preprocessing: common frame, alignment, windows, augmentations
    "wearnav.preprocess": 3,
    "wearnav.preprocess.frames": 3,
    "wearnav.preprocess.windows": 3,
    "wearnav.preprocess.augment": 3,
    # figure helpers that take arrays and recordings only (matplotlib); fixlabels, train.classify
    # and evaluate draw their checks with them, so they sit here although their folder is report/
    "wearnav.report.plots": 3,
    "wearnav.report.odometry": 3,
    # 4 models: the registry and every network / PDR
    "wearnav.models": 4,
    # 5 training, and label cleaning (fixlabels runs models.pdr; train.noisy trains on its labels)
    "wearnav.train": 5,
    "wearnav.fixlabels": 5,
    # 6 using trained models: evaluation, fusion with fixes, adaptation, export, the shipped models
    "wearnav.evaluate": 6,
    "wearnav.fuse": 6,
    "wearnav.adapt": 6,
    "wearnav.export": 6,
    "wearnav.train.resolve": 6,  # a run, a shipped name or an exported file: imports export.runtime
    "wearnav.pretrained": 6,  # the shipped models' folder and their cards
    # 7 suites and reports: benchmarks, their pages, the dataset pages, the realism report
    "wearnav.bench": 7,
    "wearnav.report": 7,
    "wearnav.realism": 7,
    "wearnav.export.speed": 7,  # a benchmark of the export formats: times them with bench.efficiency
    "wearnav.pretrained.mix": 7,  # a training mix of the real sites that bench.real_sites prepares
    "wearnav.pretrained.recipe": 7,  # makes the shipped models by running the bench suites
    "wearnav.pretrained.activity": 7,  # the shipped activity models' cards, from bench.har_lodo's results
    # 8 wearnav track: one recording to a path, its page and summary
    "wearnav.track": 8,
    "wearnav.track.files": 8,  # the names track writes, read by the CLI before torch is imported
    "wearnav.track.maps": 8,  # track's map-aware path (--map, --start): the plans and the particle filter
    "wearnav.track.trust": 8,  # whether to trust a tracked path (track, and the live tracker above it)
    "wearnav.track.write": 8,  # what track writes: the placed path, its files and page
    # runs `track` itself on held-out walks (the user's path with a radio map; only cli.bench_maps imports it)
    "wearnav.bench.radio_track": 8,
    # 9 wearnav live: the receiver; its tracker runs track's steps as data arrives
    "wearnav.live": 9,
    "wearnav.live.crowd": 9,  # every session's tracker in batched ticks: imports live.tracker
    "wearnav.live.trackers": 9,  # tracker processes beside a receiver: live.crowd, live.store, bench.executor
    # 10 the command line
    "wearnav.cli": 10,
    "wearnav.cli.bench": 10,
    "wearnav.cli.bench_fixes": 10,  # bench easytrack, easytrack-base, adapt (registered on cli_bench's app)
    "wearnav.cli.bench_maps": 10,  # bench map-lofo, radio-track (registered on cli_bench's app)
    "wearnav.cli.common": 10,
    "wearnav.cli.live": 10,
    "wearnav.cli.models": 10,
    "wearnav.cli.train": 10,
    "wearnav.cli.label": 10,
    "wearnav.__main__": 10,
}

# Upward imports tolerated today, each with its reason: (importer, imported). Empty: none is.
ALLOWED_UPWARD: set[tuple[str, str]] = set()


def modules() -> dict[str, tuple[Path, bool]]:
    """Every module under src/wearnav: dotted name → (file, is a package's __init__)."""
    found = {}
    for path in sorted((SRC / "wearnav").rglob("*.py")):
        parts = list(path.relative_to(SRC).with_suffix("").parts)
        is_pkg = parts[-1] == "__init__"
        found[".".join(parts[:-1] if is_pkg else parts)] = (path, is_pkg)
    return found


MODULES = modules()


def owning_module(name: str) -> str:
    """The module a dotted name lives in (``wearnav.a.b.func`` → ``wearnav.a.b``)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name


def wearnav_imports(module: str) -> dict[str, int]:
    """The modules of wearnav that ``module`` imports, each with the line of its first import."""
    path, is_pkg = MODULES[module]
    package = module if is_pkg else module.rpartition(".")[0]
    found: dict[str, int] = {}
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: from . import x, from ..a import b
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                origin = ".".join(base + ([node.module] if node.module else []))
            else:
                origin = node.module or ""
            targets = [f"{origin}.{a.name}" if f"{origin}.{a.name}" in MODULES else origin for a in node.names]
        for target in targets:
            if target == "wearnav" or target.startswith("wearnav."):
                imported = owning_module(target)
                if imported != module:
                    found.setdefault(imported, node.lineno)
    return found


GRAPH = {m: wearnav_imports(m) for m in MODULES}


def layer(module: str) -> int:
    """The layer of the longest prefix of ``module`` in :data:`LAYERS` (the root package ``wearnav``
    only for itself: a new top-level module needs its own row)."""
    name = module
    while name and (name != "wearnav" or module == "wearnav"):
        if name in LAYERS:
            return LAYERS[name]
        name = name.rpartition(".")[0]
    raise KeyError(module)


def find_cycles(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """One cycle (as a closed path of modules) per strongly connected component of more than one
    module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(graph[root]))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(graph[child])))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    components.append(component)
    return [cycle_in(graph, set(c)) for c in components]


def cycle_in(graph: dict[str, dict[str, int]], component: set[str]) -> list[str]:
    """A closed path through a strongly connected ``component``: a breadth-first search from its
    smallest member back to itself, within the component."""
    start = min(component)
    previous: dict[str, str] = {}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for child in sorted(graph[node]):
                if child == start:
                    path = [node]
                    while path[-1] != start:
                        path.append(previous[path[-1]])
                    return [start, *reversed(path[:-1]), start] if len(path) > 1 else [start, node, start]
                if child in component and child not in previous:
                    previous[child] = node
                    following.append(child)
        frontier = following
    raise AssertionError(f"not a cycle: {sorted(component)}")


def test_the_scan_sees_every_kind_of_import():
    """The collector finds module-level, function-level, relative and ``from pkg import module``
    imports (so a rule that passes is not passing on an empty graph)."""
    assert len(MODULES) > 100
    assert "wearnav.dataset" in GRAPH["wearnav.importers"]  # module level
    assert "wearnav.train.resolve" in GRAPH["wearnav.report.trajectory_page"]
    assert "wearnav.pretrained" in GRAPH["wearnav.track.run"]  # from wearnav import pretrained
    assert "wearnav.fuse.smoother" in GRAPH["wearnav.fuse"]  # relative or absolute, a sibling
    assert "wearnav.report.odometry" in GRAPH["wearnav.bench.real_page"]  # inside a function


def test_find_cycles_names_the_cycle():
    graph = {"a": {"b": 1}, "b": {"c": 2}, "c": {"a": 3}, "d": {"a": 4}}
    assert find_cycles(graph) == [["a", "b", "c", "a"]]
    assert find_cycles({"a": {"b": 1}, "b": {}}) == []


def test_no_import_cycles():
    cycles = find_cycles(GRAPH)
    assert not cycles, "import cycles:\n" + "\n".join(" → ".join(c) for c in cycles)


def test_every_module_has_a_layer():
    missing = []
    for module in MODULES:
        try:
            layer(module)
        except KeyError:
            missing.append(module)
    assert not missing, f"modules with no layer in LAYERS (add them, with a comment): {missing}"


def test_imports_run_downward():
    layered = {m for m in MODULES if any(m == k or m.startswith(k + ".") for k in LAYERS if k != "wearnav")}
    layered |= {"wearnav"}  # the others fail test_every_module_has_a_layer
    upward = [
        f"{m} (layer {layer(m)}, line {line}) imports {imp} (layer {layer(imp)})"
        for m, imports in GRAPH.items()
        for imp, line in sorted(imports.items())
        if m in layered and imp in layered and layer(imp) > layer(m) and (m, imp) not in ALLOWED_UPWARD
    ]
    assert not upward, "upward imports:\n" + "\n".join(upward)


def test_the_allow_list_is_still_needed():
    """An allowed upward import that is gone must leave the list."""
    stale = [p for p in sorted(ALLOWED_UPWARD) if p[1] not in GRAPH[p[0]] or layer(p[1]) <= layer(p[0])]
    assert not stale, f"no longer upward imports, remove them from ALLOWED_UPWARD: {stale}"
