"""Old import paths of diffguide 0.1, kept working for one release.

diffguide 0.1 had ~20 flat modules (``diffguide.kinematics``, ``diffguide.rails``, ...); they now
live in the layer packages. :data:`MOVED` maps each old dotted name to its new module; a meta-path
finder installed by ``diffguide/__init__.py`` makes ``import diffguide.kinematics`` (and
``from diffguide.kinematics import joint_errors``, and relative imports such as
``from ..kinematics import joint_errors`` inside the package) return the *same module object* as
the new path, so monkeypatching and ``isinstance`` keep working. Imports from outside the package
get a ``DeprecationWarning`` naming the new path; imports from inside it stay silent.

No file exists at the old location: the alias is the whole mechanism.
"""

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings

#: Old module (diffguide 0.1) -> new module.
MOVED = {
    "diffguide._types": "diffguide._core.types",
    "diffguide._checks": "diffguide._core.checks",
    "diffguide._precision": "diffguide._core.precision",
    "diffguide._newton": "diffguide._core.newton",
    "diffguide.hertz": "diffguide.contact.hertz",
    "diffguide.smoothing": "diffguide.contact.smoothing",
    "diffguide.carriage_solve": "diffguide.guideway.solve",
    "diffguide.rails": "diffguide.guideway.rails",
    "diffguide.build": "diffguide.machine.build",
    "diffguide.kinematics": "diffguide.machine.kinematics",
    "diffguide.majda2012": "diffguide.machine.majda2012",
    "diffguide.config": "diffguide.io.config",
    "diffguide.montecarlo": "diffguide.studies.montecarlo",
    "diffguide.random_rails": "diffguide.studies.random_rails",
    "diffguide.sensitivity": "diffguide.studies.sensitivity",
    "diffguide.compensation": "diffguide.studies.compensation",
    "diffguide.measurements": "diffguide.io.measurements",
}

_IMPORT_MACHINERY = ("<frozen importlib", importlib.__file__.rsplit("/", 1)[0], __file__)


def _importer(frame):
    """The first frame outside the import machinery and this module, and the ``stacklevel``
    that points :func:`warnings.warn` (called one frame below ``frame``) at it; ``warnings``
    itself skips the frozen ``importlib._bootstrap`` frames."""
    level = 2
    while frame is not None and frame.f_code.co_filename.startswith(_IMPORT_MACHINERY):
        if not frame.f_code.co_filename.startswith("<frozen importlib._bootstrap"):
            level += 1
        frame = frame.f_back
    return frame, level


def deprecated(old: str, stacklevel: int) -> None:
    """Warn that the module ``old`` moved (see :data:`MOVED`)."""
    warnings.warn(
        f"{old} moved to {MOVED[old]}; the old name works for one release",
        DeprecationWarning,
        stacklevel=stacklevel + 1,
    )


class _AliasLoader(importlib.abc.Loader):
    def __init__(self, target: str):
        self.target = target
        self.real_spec = None

    def create_module(self, spec):
        module = importlib.import_module(self.target)
        self.real_spec = module.__spec__
        return module

    def exec_module(self, module):
        # the import system set the shared module's __spec__ to the alias spec: restore it
        module.__spec__ = self.real_spec


class AliasFinder(importlib.abc.MetaPathFinder):
    """Finds the old dotted names of :data:`MOVED` and loads them as their new modules."""

    def find_spec(self, fullname, path=None, target=None):
        new = MOVED.get(fullname)
        if new is None:
            return None
        frame, level = _importer(sys._getframe(1))
        caller = "" if frame is None else frame.f_globals.get("__name__", "")
        if not (caller == "diffguide" or caller.startswith("diffguide.")):
            deprecated(fullname, level)
        return importlib.machinery.ModuleSpec(fullname, _AliasLoader(new))


def install() -> None:
    """Put the finder on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, AliasFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, AliasFinder())


def forget() -> None:
    """Drop the old names that the package's own modules imported (silently) while
    ``diffguide`` was being imported, so that a user's first import of an old name still goes
    through the finder and gets its warning. The modules themselves stay loaded."""
    package = sys.modules.get("diffguide")
    for old in MOVED:
        if sys.modules.pop(old, None) is not None and package is not None:
            package.__dict__.pop(old.rsplit(".", 1)[1], None)
