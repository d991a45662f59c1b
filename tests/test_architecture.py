"""The import rules of docs/architecture.md, read from the code with ``ast`` (imports inside
functions count as much as those at the top of a module)."""

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("meshgen", "spinweb_fe")
#: stages from the bottom up: a module may import only its own stage and the ones below
LAYERS = ("meshgen", "spinweb_fe.errors", "spinweb_fe.fe", "spinweb_fe.record", "spinweb_fe.io",
          "spinweb_fe.linear", "spinweb_fe.case", "spinweb_fe.run", "spinweb_fe.analytic",
          "spinweb_fe.post", "spinweb_fe.sweep", "spinweb_fe.cli", "spinweb_fe.__main__")
MAX_LINES = 500
#: ... and no module within 10 % of it: the limit met by structure, not by squeezing
ROOM = 0.9
#: the folders of scripts beside the package (tests never import them)
SCRIPTS = ("benchmarks", "studies", "tools")
MAX_KERNEL_PARAMS = 14


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def library_modules() -> dict:
    """{module name: path} of every module of the two packages."""
    return {module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def imports_of(path: Path, name: str, known) -> set:
    """Project modules that ``path`` imports anywhere in its body. ``from a.b import c`` is an
    import of a.b.c when that is a module, else of a.b."""
    tree = ast.parse(path.read_text(), str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(up + ([base] if base else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base
                       for a in node.names]
        else:
            continue
        found.update(t for t in targets if t.split(".")[0] in PACKAGES + SCRIPTS)
    return found


@pytest.fixture(scope="module")
def graph():
    mods = library_modules()
    return {name: imports_of(path, name, mods) for name, path in mods.items()}


def layer(name: str) -> int:
    best = max((i for i, p in enumerate(LAYERS) if name == p or name.startswith(p + ".")),
               default=None)
    assert best is not None, f"{name} belongs to no stage of LAYERS"
    return best


def test_every_module_has_a_stage(graph):
    for name in graph:
        if name != "spinweb_fe":  # the package's face: version numbers only
            layer(name)


def test_no_import_cycles(graph):
    state = {}

    def visit(node, path):
        state[node] = "open"
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                cycle = path[path.index(nxt):] + [nxt]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])


def test_stages_only_look_down(graph):
    bad = [f"{a} -> {b}" for a, deps in graph.items() for b in deps
           if a != "spinweb_fe" and b != "spinweb_fe" and layer(b) > layer(a)]
    assert not bad, "imports that look up: " + "; ".join(sorted(bad))


def test_meshgen_imports_nothing_of_the_solver(graph):
    bad = [f"{a} -> {b}" for a, deps in graph.items() if a.startswith("meshgen")
           for b in deps if not b.startswith("meshgen")]
    assert not bad, bad


def test_fe_imports_only_the_mesh_value_numpy_and_numba():
    mods = library_modules()
    for name, path in mods.items():
        if not name.startswith("spinweb_fe.fe"):
            continue
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                roots = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                roots = [node.module or ""]
            else:
                continue
            for r in roots:
                top = r.split(".")[0]
                # (llvmlite: numba's own code generator, for an intrinsic: fe.contact.clock)
                allowed = (top in ("numpy", "numba", "llvmlite") or r == "meshgen.mesh"
                           or r.startswith("spinweb_fe.fe") or top in sys.stdlib_module_names)
                assert allowed, f"{name} imports {r}"


def test_record_and_io_never_import_run(graph):
    bad = [f"{a} -> {b}" for a, deps in graph.items()
           if a.startswith(("spinweb_fe.record", "spinweb_fe.io")) for b in deps
           if b.startswith("spinweb_fe.run")]
    assert not bad, bad


def test_nothing_imports_the_command_line(graph):
    bad = [f"{a} -> {b}" for a, deps in graph.items() for b in deps
           if b.startswith("spinweb_fe.cli") and not a.startswith(("spinweb_fe.cli",
                                                                    "spinweb_fe.__main__"))]
    assert not bad, bad


def test_tests_never_import_the_scripts():
    mods = library_modules()
    for path in sorted((ROOT / "tests").glob("*.py")):
        deps = imports_of(path, "tests." + path.stem, mods)
        assert not any(d.split(".")[0] in SCRIPTS for d in deps), path.name
        text = path.read_text()
        assert "spec_from_file_location" not in text or path.name == Path(__file__).name, \
            f"{path.name} loads a file by path"


def test_library_modules_stay_small():
    """Modules stay under MAX_LINES, and out of its last 10 % (split by what they do, not
    squeezed to fit)."""
    cap = int(ROOM * MAX_LINES)
    big = {name: n for name, p in library_modules().items()
           if (n := len(p.read_text().splitlines())) > cap}
    assert not big, f"modules over {cap} lines ({ROOM:.0%} of {MAX_LINES}): {big}"


def _jitted(node) -> bool:
    """A function decorated with numba's njit / jit (called or not)."""
    for d in node.decorator_list:
        target = d.func if isinstance(d, ast.Call) else d
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in ("njit", "jit"):
            return True
    return False


def kernel_params(tree) -> dict:
    """{function name: parameter count} of the jitted functions of a module."""
    return {n.name: len(n.args.args) + len(n.args.kwonlyargs) for n in ast.walk(tree)
            if isinstance(n, ast.FunctionDef) and _jitted(n)}


def test_kernels_take_few_parameters():
    """No jitted function takes more than 14 parameters: arrays are grouped by entity
    (docs/architecture.md)."""
    big = {f"{name}.{fn}": n for name, p in library_modules().items()
           for fn, n in kernel_params(ast.parse(p.read_text())).items() if n > MAX_KERNEL_PARAMS}
    assert not big, big
    counted = kernel_params(ast.parse("@njit(cache=True)\ndef f(a, b=None):\n    pass\n"
                                      "@numba.njit\ndef g(*, c):\n    pass\n"))
    assert counted == {"f": 2, "g": 1}  # the reader sees decorated kernels


def test_the_rules_see_what_they_guard(graph, tmp_path):
    """The reader is not vacuous: the loop imports the step kernels, an import inside a
    function is seen, and a relative import resolves to its module."""
    assert "spinweb_fe.fe.step" in graph["spinweb_fe.run.loop"]
    assert "spinweb_fe.run.driver" in graph["spinweb_fe.cli.run"]  # imported inside run()
    probe = tmp_path / "probe.py"
    probe.write_text("def f():\n    from .step import advance\n    from . import model\n")
    found = imports_of(probe, "spinweb_fe.fe.probe", library_modules())
    assert found == {"spinweb_fe.fe.step", "spinweb_fe.fe.model"}


#: the Coil fields that hold a registry's code (fe.coil.levels.Coil)
CODE_FIELDS = ("payout_code", "bundle_code", "coil_code")


def literal_codes(tree) -> list:
    """Comparisons of a registry code field with a number literal (``coil.payout_code >=
    2``): the line numbers."""
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Compare):
            continue
        sides = [node.left, *node.comparators]
        coded = any(isinstance(s, ast.Attribute) and s.attr in CODE_FIELDS for s in sides)
        literal = any(isinstance(s, ast.Constant) and isinstance(s.value, (int, float))
                      and not isinstance(s.value, bool) for s in sides)
        if coded and literal:
            found.append(node.lineno)
    return found


def test_no_literal_registry_codes():
    """What a payout, bundle or coil code means is its registry entry's (``Payout.device``,
    ``Bundle.timed``, ``Coil.device``): no code compared with a number anywhere."""
    bad = {name: lines for name, p in library_modules().items()
           if (lines := literal_codes(ast.parse(p.read_text())))}
    assert not bad, bad
    assert literal_codes(ast.parse("if coil.payout_code >= 2:\n    pass\n")) == [1]
    assert literal_codes(ast.parse("if coil.device:\n    pass\n")) == []


def test_every_feature_keeps_its_memory():
    """Every registered feature carries its state through a checkpoint: a memory of its own
    (record.feature.Feature.memory) or State arrays the checkpoint saves whole."""
    from spinweb_fe.case import loads
    from spinweb_fe.case.scene import prepare
    from spinweb_fe.fe.state import to_arrays
    from spinweb_fe.record.feature import Feature
    from spinweb_fe.run.features import FEATURES

    state = prepare(loads("[tethers]\ncount = 2\nlength = 5.0\nelements = 4\n"
                          "[time]\nend = 0.01\n")).state
    saved = set(to_arrays(state))
    for entry in FEATURES:
        assert issubclass(entry.cls, Feature) and entry.cls.name == entry.name, entry.name
        own = entry.cls.memory is not Feature.memory
        assert own or entry.cls.state_fields, f"{entry.name} has no memory"
        missing = set(entry.cls.state_fields) - saved
        assert not missing, (entry.name, missing)


def test_the_event_loop_names_no_feature():
    """run.loop.simulate iterates over the run's features (run.features) and names none of
    them: no feature's name, class or hook appears in its source."""
    import inspect

    from spinweb_fe.record.feature import HOOKS
    from spinweb_fe.run import loop
    from spinweb_fe.run.features import FEATURES

    words = set(HOOKS) | {e.name for e in FEATURES} | {e.cls.__name__ for e in FEATURES}
    words |= {"audit", "rupture", "tidal", "strength", "crossing", "linking", "contact"}
    tokens = {t for t in ast.walk(ast.parse(inspect.getsource(loop.simulate)))
              if isinstance(t, (ast.Name, ast.Attribute))}
    names = {getattr(t, "id", None) or t.attr for t in tokens}
    assert not names & words, names & words
    fn = ast.parse(inspect.getsource(loop.simulate)).body[0]
    code = fn.end_lineno - fn.body[0].end_lineno  # the lines after its docstring
    assert code <= 90, f"simulate has {code} lines of code"


#: (function, parameter): an else after `if parameter is not None` that is meant, and cheap
#: (a copy of x_n; the fixed axis's turn as a 4 x 3 map)
DEAD_ELSE_ALLOWED = {("touch_begin", "audit"), ("contact_resolve", "body")}


def dead_else_branches(tree) -> list:
    """(function, parameter, line) of each ``if P is not None: ... else: ...`` (or ``A if P
    is not None else B``) on a parameter P of a jitted function. numba prunes a branch only
    when its test is known from the types, and for ``P is not None`` that is only when P is
    None: with P given the else is typed and compiled too, with every function it calls (an
    else of ``axis is not None`` compiled the free hub's contact passes into every
    fixed-axis run). Two ifs, on the two parameters, prune instead."""
    found = []
    for fn in ast.walk(tree):
        if not (isinstance(fn, ast.FunctionDef) and _jitted(fn)):
            continue
        params = {a.arg for a in fn.args.args + fn.args.kwonlyargs}
        for node in ast.walk(fn):
            if not (isinstance(node, (ast.If, ast.IfExp)) and node.orelse):
                continue
            t = node.test
            if (isinstance(t, ast.Compare) and len(t.ops) == 1
                    and isinstance(t.ops[0], ast.IsNot) and isinstance(t.left, ast.Name)
                    and t.left.id in params and isinstance(t.comparators[0], ast.Constant)
                    and t.comparators[0].value is None):
                found.append((fn.name, t.left.id, node.lineno))
    return found


def test_no_else_on_a_given_argument():
    """No jitted function has an else after ``if P is not None`` on its parameter P (see
    :func:`dead_else_branches`), but for the few of DEAD_ELSE_ALLOWED; the reader finds the
    pattern, in both forms, and not the two-if form."""
    bad = [(name, *hit) for name, p in library_modules().items()
           for hit in dead_else_branches(ast.parse(p.read_text()))
           if hit[:2] not in DEAD_ELSE_ALLOWED]
    assert not bad, bad
    probe = ast.parse("@njit\ndef f(axis, body):\n    if axis is not None:\n        a = 1\n"
                      "    else:\n        a = 2\n    b = 1 if body is not None else 2\n"
                      "    if axis is not None:\n        a = 3\n    if body is not None:\n"
                      "        a = 4\n    return a + b\n")
    assert [h[:2] for h in dead_else_branches(probe)] == [("f", "axis"), ("f", "body")]

