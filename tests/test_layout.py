"""The package layout: layers visible at the top level, old import paths kept for one release."""

import importlib
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import diffguide
from diffguide._core.aliases import MOVED

PACKAGE = Path(diffguide.__file__).parent


def test_top_level_shows_the_layers():
    markers = ("__pycache__", "py.typed")  # not modules: the byte-code cache, PEP 561 marker
    entries = sorted(
        p.name for p in PACKAGE.iterdir() if p.name not in markers and not p.name.startswith(".")
    )
    assert len(entries) <= 12, entries
    assert "measurements.py" not in entries  # now io/measurements.py + inverse/data.py


@pytest.mark.parametrize("old", sorted(MOVED))
def test_old_module_path_is_the_new_module_and_warns(old):
    new = importlib.import_module(MOVED[old])
    sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match=MOVED[old].replace(".", r"\.")):
        alias = importlib.import_module(old)
    assert alias is new
    assert alias.__spec__.name == MOVED[old]  # the shared module keeps its own spec
    assert not (PACKAGE / (old.split(".")[-1] + ".py")).exists()


def test_old_from_imports_and_attributes():
    from diffguide.machine.kinematics import joint_errors as new

    sys.modules.pop("diffguide.kinematics", None)
    with pytest.warns(DeprecationWarning):
        from diffguide.kinematics import joint_errors
    assert joint_errors is new
    vars(diffguide).pop("sensitivity", None)  # set by an earlier import of the old path
    with pytest.warns(DeprecationWarning):
        assert diffguide.sensitivity is importlib.import_module("diffguide.studies.sensitivity")
    # modules that kept their name are packages re-exporting what they had
    from diffguide.contact import HertzBall
    from diffguide.guideway import Carriage, majda2012_carriage  # noqa: F401
    from diffguide.io import atomic_savefig, read_rails_csv  # noqa: F401
    from diffguide.machine import Machine, equilibrium, point_motion, rigid_body_map  # noqa: F401

    assert HertzBall is diffguide.HertzBall


def test_old_names_of_moved_functions_and_dicts_still_work_and_warn():
    """diffguide 0.1's names that moved within a module's layer (the tests use the new ones):
    ``fe.majda2012_table``, ``build.carriage_from_config``/``table_from_config``,
    ``build_machine(config dict)`` and ``presets.MAJDA2012_TABLE`` — each still answers, with a
    DeprecationWarning naming where it went."""
    import diffguide.fe as fe
    import diffguide.machine.build as build
    import diffguide.presets as presets
    from diffguide.io import config
    from diffguide.machine.majda2012 import majda2012_table

    with pytest.warns(DeprecationWarning, match=r"diffguide\.machine\.majda2012"):
        assert fe.majda2012_table is majda2012_table
    for name in ("carriage_from_config", "table_from_config"):
        with pytest.warns(DeprecationWarning, match=rf"diffguide\.io\.config\.{name}"):
            assert getattr(build, name) is getattr(config, name)
    with pytest.warns(DeprecationWarning, match=r"presets\.majda2012\(\)"):
        assert presets.MAJDA2012_TABLE["thickness"] == presets.majda2012().table.thickness
    cfg = config.default_config()
    with pytest.warns(DeprecationWarning, match="MachineSpec"):
        old = build.build_machine(cfg, nx=4, ny=2)
    new = build.build_machine(config.spec_from_config(cfg), nx=4, ny=2)
    assert old.point_names == new.point_names
    assert np.array_equal(np.asarray(old.table.K), np.asarray(new.table.K))


@pytest.mark.parametrize(
    "statement",
    [
        "from ..kinematics import joint_errors",
        "from ..machine import Machine",
        "from ..rails import SplineRail",
        "from .._precision import require_x64",
        "from .._types import Array, Float",
        "from ..measurements import QUANTITIES",
    ],
)
def test_relative_old_imports_inside_the_package_are_silent(statement):
    for old in MOVED:
        sys.modules.pop(old, None)
    scope = {"__name__": "diffguide.inverse._probe", "__package__": "diffguide.inverse"}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        exec(statement, scope)


# --- the core does not know about files, formats, the CLI or plotting ------------------------

CORE = ("_core", "contact", "guideway", "fe", "machine", "inverse")
EDGE = ("diffguide.io", "diffguide.cli", "diffguide.plotting", "diffguide.measurements")
FORMATS = ("csv", "tomllib", "json", "argparse", "matplotlib")
#: Imports from the core to the edge inside a function, each a documented convenience.
ALLOWED = {
    ("machine/kinematics.py", "diffguide.io.units"),  # JointErrors.user_units()
    # build_machine(dict) and carriage/table_from_config: the deprecated 0.1 paths
    ("machine/build.py", "diffguide.io.config"),
}


def _imports(path: Path):
    """``(module, absolute name)`` of every import in a file (module level or not)."""
    import ast

    rel = path.relative_to(PACKAGE)
    package = ["diffguide", *rel.parent.parts]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                name = ".".join(base + ([node.module] if node.module else []))
            else:
                name = node.module
            yield name
            for alias in node.names:  # "from .. import presets"
                yield f"{name}.{alias.name}"


def test_core_imports_no_file_formats_cli_or_plotting():
    bad = []
    for top in CORE:
        for path in sorted((PACKAGE / top).rglob("*.py")):
            rel = str(path.relative_to(PACKAGE))
            for name in _imports(path):
                edge = name.startswith(EDGE) or name.split(".")[0] in FORMATS
                allowed = any(
                    rel == r and (name == p or name.startswith(p + ".") or p.startswith(name + "."))
                    for r, p in ALLOWED
                )
                if edge and not allowed:
                    bad.append(f"{rel}: {name}")
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
