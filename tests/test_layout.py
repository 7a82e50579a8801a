"""The package layout: the layers in one order, every import going down it.

``_core -> contact -> guideway -> fe -> machine -> inverse -> planning -> studies -> io ->
plotting -> jobs -> cli``, then ``__main__`` (``python -m diffguide``: the CLI's entry),
``presets`` (data the CLI and users choose) and the root ``__init__`` (the public namespace). A module imports only from its own layer or an earlier one, at module level and
inside functions alike; the one exception is the CLI's lazy imports inside its functions (a fast
``--help``). Nothing in the library imports ``presets``.
"""

import ast
import subprocess
import sys
from pathlib import Path

import diffguide

PACKAGE = Path(diffguide.__file__).parent
LAYERS = ("_core", "contact", "guideway", "fe", "machine", "inverse", "planning", "studies", "io",
          "plotting", "jobs", "cli", "__main__", "presets", "__init__")
RANK = {name: i for i, name in enumerate(LAYERS)}


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE).with_suffix("")
    parts = ["diffguide", *rel.parts]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _layer(module: str) -> str:
    """The layer of a dotted ``diffguide...`` module name (``diffguide`` itself: the root)."""
    parts = module.split(".")
    return "__init__" if len(parts) == 1 else parts[1]


MODULES = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imports(path: Path):
    """``(line, target module, module level?)`` for every import of ``diffguide`` in a file,
    relative or absolute, at module level or inside functions and classes."""
    module = _module_name(path)
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    top = {id(node) for node in tree.body}
    top |= {id(n) for node in tree.body if isinstance(node, (ast.If, ast.Try))
            for n in ast.walk(node)}  # `if TYPE_CHECKING:` / `try:` at module level
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                base = ".".join(base + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            # "from .. import presets" imports a module; "from .x import y" imports from .x
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base
                     for a in node.names]
        for name in dict.fromkeys(names):  # a name that is no module file: reported as such
            if name == "diffguide" or name.startswith("diffguide."):
                yield node.lineno, name, id(node) in top


def _edges():
    for module, path in MODULES.items():
        for line, target, at_top in _imports(path):
            if target != module:
                yield module, path, line, target, at_top


def test_every_module_has_a_layer():
    assert {_layer(m) for m in MODULES} <= set(LAYERS)


def test_every_import_names_a_module_file():
    """No import goes through a name without a file (an import hook's alias)."""
    bad = [
        f"{path.relative_to(PACKAGE)}:{line} -> {target}"
        for _, path, line, target, _ in _edges()
        if target not in MODULES
    ]
    assert not bad, "imports of modules that do not exist:\n" + "\n".join(bad)


def test_imports_go_down_the_layers():
    bad = []
    for module, path, line, target, at_top in _edges():
        here, there = _layer(module), _layer(target)
        if here in ("presets", "__init__"):
            continue  # data chosen from above, and the public namespace
        if here == "cli" and not at_top:
            continue  # lazy imports inside the CLI's functions
        if there not in RANK or RANK[there] > RANK[here]:
            bad.append(f"{path.relative_to(PACKAGE)}:{line} -> {target}")
    assert not bad, "imports up the layers:\n" + "\n".join(bad)


def test_only_the_cli_and_the_root_import_presets():
    bad = [
        f"{path.relative_to(PACKAGE)}:{line} -> {target}"
        for module, path, line, target, _ in _edges()
        if _layer(target) == "presets" and _layer(module) not in ("cli", "presets", "__init__")
    ]
    assert not bad, bad


def _cycles(graph):
    """Every cycle a depth-first search over ``graph`` (module -> imported modules) meets."""
    cycles, state, stack = [], {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                cycles.append(" -> ".join(stack[stack.index(nxt):] + [nxt]))
            elif nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node)
    return cycles


def test_no_import_cycles():
    """No cycle among the modules' module-level imports."""
    graph = {module: set() for module in MODULES}
    for module, _, _, target, at_top in _edges():
        if at_top and target in MODULES:
            graph[module].add(target)
    cycles = _cycles(graph)
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def test_no_import_cycles_through_functions():
    """Counting the imports inside functions too, no cycle outside the CLI and the root (they
    sit above everything and import lazily): a lazy import hides a cycle, it does not remove
    it."""
    top = ("cli", "__init__")
    graph = {module: set() for module in MODULES if _layer(module) not in top}
    for module, _, _, target, _ in _edges():
        if target in MODULES and _layer(module) not in top and _layer(target) not in top:
            graph[module].add(target)
    cycles = _cycles(graph)
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def test_import_leaves_the_import_system_alone():
    code = (
        "import sys; before = list(sys.meta_path); import diffguide; "
        "diffguide.Material; diffguide.presets; "
        "assert sys.meta_path == before, sys.meta_path"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=300)


def test_no_module_getattr_except_the_root():
    bad = []
    for module, path in MODULES.items():
        if module == "diffguide":
            continue
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.FunctionDef) and node.name == "__getattr__":
                bad.append(str(path.relative_to(PACKAGE)))
    assert not bad, bad


def test_no_compatibility_modules():
    for rel in ("_core/aliases.py", "io/files.py"):
        assert not (PACKAGE / rel).exists(), rel
    for old in ("kinematics", "rails", "config", "measurements", "_precision", "_types"):
        assert not (PACKAGE / f"{old}.py").exists()
        code = f"import diffguide.{old}"
        run = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=300)
        assert run.returncode != 0 and b"ModuleNotFoundError" in run.stderr, code


def test_top_level_shows_the_layers():
    markers = ("__pycache__", "py.typed")  # not modules: the byte-code cache, PEP 561 marker
    entries = sorted(
        p.name for p in PACKAGE.iterdir() if p.name not in markers and not p.name.startswith(".")
    )
    assert len(entries) <= len(LAYERS), entries
    assert {p.split(".")[0] for p in entries} == set(LAYERS)


def test_public_names_answer():
    """Every public name of the root namespace resolves, and the layer packages re-export
    what they had."""
    for name in diffguide.__all__:
        assert getattr(diffguide, name) is not None, name
    from diffguide.contact import HertzBall
    from diffguide.guideway import Carriage, majda2012_carriage  # noqa: F401
    from diffguide.io import atomic_savefig, read_rails_csv  # noqa: F401
    from diffguide.machine import Machine, equilibrium, point_motion, rigid_body_map  # noqa: F401

    assert HertzBall is diffguide.HertzBall


# --- the core does not know about files, formats, the CLI or plotting ------------------------

CORE = ("_core", "contact", "guideway", "fe", "machine", "inverse")
FORMATS = ("csv", "tomllib", "json", "argparse", "matplotlib")


def test_core_imports_no_file_formats():
    bad = []
    for top in CORE:
        for path in sorted((PACKAGE / top).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Import):
                    names = [alias.name for alias in node.names]
                elif isinstance(node, ast.ImportFrom) and not node.level:
                    names = [node.module or ""]
                else:
                    continue
                bad += [f"{path.relative_to(PACKAGE)}:{node.lineno} {n}" for n in names
                        if n.split(".")[0] in FORMATS]
    assert not bad, bad


def test_no_process_state_outside_the_cli():
    bad = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        if rel.parts[0] == "cli":
            continue
        text = path.read_text(encoding="utf-8")
        for needle in ("os.environ[", "XLA_FLAGS", "matplotlib.use(", "jax.config.update("):
            if needle in text and not (
                needle == "jax.config.update(" and rel.name == "precision.py"
            ):
                bad.append(f"{rel}: {needle}")
    assert not bad, bad


#: the most lines of a module of the command line: argument parsing and printing, a screen or
#: two; the work is the job's (diffguide.jobs)
MAX_CLI_LINES = 250


def _cli_commands() -> dict:
    """``{module name: path}`` of the CLI's command modules (``diffguide.cli.X`` for X a
    command's module; the helpers ``cli/_*.py`` and the package files are not commands)."""
    from diffguide.cli import _COMMANDS

    return {f"diffguide.cli.{m}": PACKAGE / "cli" / f"{m}.py" for m in _COMMANDS.values()}


def test_every_public_cli_module_is_a_command():
    """A module of cli/ without a leading underscore is a command (its helpers are private):
    what the next test checks covers every module that could hold a command's work."""
    public = {p.stem for p in (PACKAGE / "cli").glob("*.py")
              if not p.name.startswith("_")}
    assert public == {m.rsplit(".", 1)[1] for m in _cli_commands()}


def test_no_command_imports_another_command():
    """A command that imports another is sharing work that belongs in a job or a helper."""
    commands = _cli_commands()
    bad = [f"{path.relative_to(PACKAGE)}:{line}: {target}"
           for module, path in commands.items()
           for line, target, _ in _imports(path)
           if target != module and any(target == c or target.startswith(c + ".")
                                       for c in commands)]
    assert not bad, bad


def test_every_cli_module_is_short():
    long = {str(p.relative_to(PACKAGE)): n for p in sorted((PACKAGE / "cli").glob("*.py"))
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_CLI_LINES}
    assert not long, f"over {MAX_CLI_LINES} lines: {long}"
