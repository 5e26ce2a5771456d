"""The structure of the package, read from its imports: the layers of
``../shared/docs/architecture.md`` and the habits that keep it easy to extend.

Each module of ``masonry_nscd`` is parsed (not imported) and its imports of the package are
collected: at the top of the module, or inside a function (a lazy import). An import names the
module it takes (``from masonry_nscd.nscd import pardiso`` takes ``nscd/pardiso.py``; ``from
masonry_nscd.case import Case`` takes ``case``). From these:

* circles: sets of modules that import one another, directly or through others;
* arrows that run back up: a module importing one of a higher layer (:data:`LAYERS`);
* imports of private names (``_name``) from another module;
* the largest modules and the functions over 120 lines.

``python tests/test_architecture.py`` prints the table of these figures.
"""

from __future__ import annotations

import ast
import sys
from dataclasses import dataclass, field
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "masonry_nscd"

#: The layers from the bottom: a module may import its own layer and those below. The first
#: prefix that matches a module's dotted name (without ``masonry_nscd.``) gives its layer.
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("base", ("__init__", "errors", "timing", "threads", "arithmetic")),
    ("physics", ("loading", "fe", "contact")),
    ("model", ("model",)),
    ("materials", ("materials",)),
    ("schema", ("case",)),
    ("step", ("nscd",)),
    ("files", ("io",)),
    ("builders", ("scenes",)),
    ("post", ("post",)),
    ("run", ("report", "collapse", "figure_files", "plots", "plots_limit", "run", "warmup",
             "limit")),
    ("studies", ("studies",)),
    ("cli", ("cli",)),
]


def layer_of(module: str) -> int:
    """The index in :data:`LAYERS` of ``module`` (dotted, without the package's name)."""
    for i, (_, prefixes) in enumerate(LAYERS):
        if any(module == p or module.startswith(p + ".") for p in prefixes):
            return i
    raise KeyError(f"module {module} is in no layer of LAYERS")


@dataclass
class Module:
    name: str  # dotted, without the package's name ("nscd.pardiso"; "__init__" for the package)
    lines: int
    imports: set[str] = field(default_factory=set)  # modules imported at the top
    lazy: set[str] = field(default_factory=set)  # modules imported inside functions
    private: list[str] = field(default_factory=list)  # "module._name" imported from others
    long_functions: list[tuple[str, int]] = field(default_factory=list)


def _module_name(path: Path) -> str:
    rel = path.relative_to(PKG).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__" and len(parts) > 1:
        parts = parts[:-1]
    return ".".join(parts)


def _is_module(dotted: str) -> bool:
    base = PKG.joinpath(*dotted.split("."))
    return base.with_suffix(".py").exists() or (base / "__init__.py").exists()


def read_package() -> dict[str, Module]:
    """Every module of the package with its imports of the package."""
    out: dict[str, Module] = {}
    for path in sorted(PKG.rglob("*.py")):
        text = path.read_text()
        tree = ast.parse(text)
        mod = Module(_module_name(path), len(text.splitlines()))
        package = mod.name if path.name == "__init__.py" else mod.name.rpartition(".")[0]
        top = set(map(id, tree.body))
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                size = (node.end_lineno or node.lineno) - node.lineno + 1
                if size > 120:
                    mod.long_functions.append((node.name, size))
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            targets = _targets(node, package)
            if not targets:
                continue
            (mod.imports if id(node) in top or _in_type_checking(tree, node) else
             mod.lazy).update(t for t, _ in targets if t != mod.name)
            mod.private += [f"{t}.{n}" for t, n in targets
                            if n and n.startswith("_") and t != mod.name]
        out[mod.name] = mod
    return out


def _targets(node: ast.Import | ast.ImportFrom, package: str) -> list[tuple[str, str | None]]:
    """The package's modules an import takes, each with the name taken from it (None for a
    module taken whole)."""
    out: list[tuple[str, str | None]] = []
    if isinstance(node, ast.Import):
        for a in node.names:
            if a.name == "masonry_nscd" or a.name.startswith("masonry_nscd."):
                out.append((a.name.removeprefix("masonry_nscd").lstrip(".") or "__init__", None))
        return out
    if node.level:
        base = package.split(".") if package and package != "__init__" else []
        base = base[:len(base) - node.level + 1]
        source = ".".join([*base, *(node.module.split(".") if node.module else [])])
    elif node.module == "masonry_nscd" or (node.module or "").startswith("masonry_nscd."):
        source = node.module.removeprefix("masonry_nscd").lstrip(".")
    else:
        return out
    for a in node.names:
        sub = f"{source}.{a.name}" if source else a.name
        if _is_module(sub):
            out.append((sub, None))
        else:
            out.append((source or "__init__", a.name))
    return out


def _in_type_checking(tree: ast.Module, node: ast.AST) -> bool:
    for stmt in tree.body:
        if (isinstance(stmt, ast.If) and "TYPE_CHECKING" in ast.unparse(stmt.test)
                and any(n is node for n in ast.walk(stmt))):
            return True
    return False


def circles(modules: dict[str, Module]) -> list[list[str]]:
    """The sets of two or more modules that import one another (Tarjan's strongly connected
    components of the import graph, lazy imports included)."""
    graph = {m: sorted((mod.imports | mod.lazy) & modules.keys()) for m, mod in modules.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []
    counter = [0]
    sys.setrecursionlimit(max(10000, sys.getrecursionlimit()))

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def back_up(modules: dict[str, Module]) -> list[str]:
    """The imports from a module to one of a higher layer (``"a -> b"``)."""
    out = []
    for m, mod in modules.items():
        for t in sorted((mod.imports | mod.lazy) & modules.keys()):
            if m != "__init__" and t != "__init__" and layer_of(t) > layer_of(m):
                out.append(f"{m} -> {t}")
    return out


def table(modules: dict[str, Module]) -> str:
    """The figures of the module docstring, as text."""
    rows = []
    largest = sorted(modules.values(), key=lambda m: -m.lines)[:5]
    rows.append("largest modules: " + ", ".join(f"{m.name} {m.lines}" for m in largest))
    cs = circles(modules)
    rows.append(f"import circles: {len(cs)}" + "".join(f"\n  {' <-> '.join(c)}" for c in cs))
    up = back_up(modules)
    rows.append(f"arrows that run back up: {len(up)}" + "".join(f"\n  {a}" for a in up))
    private = [(m.name, p) for m in modules.values() for p in m.private]
    rows.append(f"imports of private names: {len(private)}"
                + "".join(f"\n  {m} takes {p}" for m, p in private))
    lazy = sum(len(m.lazy - m.imports) for m in modules.values())
    total = sum(len(m.lazy | m.imports) for m in modules.values())
    rows.append(f"internal imports inside functions: {lazy} of {total} (module pairs)")
    long = sorted(((n, f, s) for m in modules.values() for f, s in m.long_functions
                   for n in [m.name]), key=lambda x: -x[2])
    rows.append(f"functions over 120 lines: {len(long)}"
                + "".join(f"\n  {n}.{f} {s}" for n, f, s in long))
    return "\n".join(rows)


def test_every_module_has_a_layer():
    for name in read_package():
        layer_of(name)


#: Modules outside ``io/`` that may name a run-folder file in a string: the schema's help
#: texts (``case/``), and the CLI's help texts and its resume check (``cli.py``).
NAMES_ALLOWED = ("case", "cli")


def _strings(tree: ast.Module) -> list[ast.Constant]:
    """The string constants of a module that are not docstrings (f-strings' parts included)."""
    docs = {id(node.body[0].value) for node in ast.walk(tree)
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
            and node.body and isinstance(node.body[0], ast.Expr)
            and isinstance(node.body[0].value, ast.Constant)}
    return [node for node in ast.walk(tree) if isinstance(node, ast.Constant)
            and isinstance(node.value, str) and id(node) not in docs]


def test_only_io_names_the_run_folder_files():
    """The names of the run folder's files are the constants of ``io/runfolder.py``."""
    from masonry_nscd.io import limit_analysis as la
    from masonry_nscd.io import runfolder as rf

    names = [rf.CASE, rf.SCENE, rf.CSV, rf.ENERGY, rf.RESULTS, rf.PVD, rf.CHECKPOINT, rf.SUMMARY,
             rf.CYCLES, rf.ENVELOPE, rf.LOG, rf.LIMIT_CSV, rf.LIMIT_JSON, rf.SWEEP_MARKER,
             la.MECHANISM_VTU, la.MECHANISM_PNG, la.JOINT_FORCES_CSV, la.JOINT_FORCES_VTU]
    found = []
    for path in sorted(PKG.rglob("*.py")):
        module = _module_name(path)
        if any(module == m or module.startswith(m + ".") for m in ("io", *NAMES_ALLOWED)):
            continue
        for node in _strings(ast.parse(path.read_text())):
            found += [f"{module}:{node.lineno} {n}" for n in names if n in node.value]
    assert not found, found


def test_only_io_opens_hdf5_files():
    """No module outside ``io/`` imports h5py: the results file is read through io/."""
    found = []
    for path in sorted(PKG.rglob("*.py")):
        module = _module_name(path)
        if module == "io" or module.startswith("io."):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import) and any(a.name.split(".")[0] == "h5py"
                                                    for a in node.names) or \
                    isinstance(node, ast.ImportFrom) and (node.module or "").startswith("h5py"):
                found.append(f"{module}:{node.lineno}")
    assert not found, found



def test_every_structure_has_its_builder_and_every_builder_its_structure():
    """A structure is its section module in ``case/structures/`` and its builder module in
    ``scenes/``, each found by discovery: the two registries name the same structures, the
    default one (the wall) first, and the case model has a field for each."""
    from masonry_nscd.case import Case
    from masonry_nscd.case.structures import structures
    from masonry_nscd.scenes import builders

    names = [s.name for s in structures()]
    assert names[0] == "wall" and structures()[0].default
    assert set(names) == set(builders())
    assert all(name in Case.model_fields for name in names)


def test_the_schema_imports_nothing_above_it():
    """The case schema reads no builder, solver, run folder or study: its imports of the
    package stay within the layers below it (the arrows back up of :func:`back_up`)."""
    modules = read_package()
    schema = [m for m in modules if layer_of(m) == layer_of("case")]
    up = [a for a in back_up(modules) if a.split(" -> ")[0] in schema]
    assert not up, up


if __name__ == "__main__":
    print(table(read_package()))
