"""A griffe extension for the API page: the public names as diffguide's packages export them.

- A subpackage re-exports its public names explicitly (``from .laws import HertzBall as
  HertzBall``) without an ``__all__``; griffe treats imported names as private unless listed
  there. Every such alias that points inside the package is marked public, so that
  ``::: diffguide.contact`` documents the names a user imports from it.
- A compiled entry point, ``joint_errors = eqx.filter_jit(joint_errors_traced)``, takes the
  docstring of the function it compiles.
- The top-level package loads its public API lazily from the ``_LAZY`` table (name -> the module
  that defines it), which static analysis cannot see; the table is read from the source and each
  name becomes an alias, so that ``::: diffguide.read_measurements`` finds the function wherever
  the table says it lives.
"""

import ast
import re

import griffe

#: ``name = eqx.filter_jit(name_traced)``, ``name = jax.jit(f)``: a compiled entry point
_JITTED = re.compile(r"jit\((\w+)\)$")


class PublicReexports(griffe.Extension):
    """Mark re-exported names public; add the top-level package's lazy names."""

    def on_package(self, *, pkg: griffe.Module, **kwargs) -> None:
        self._add_lazy(pkg)
        self._mark(pkg, pkg.path + ".")

    def _add_lazy(self, pkg: griffe.Module) -> None:
        if pkg.filepath is None or not str(pkg.filepath).endswith("__init__.py"):
            return
        for name, module in _lazy_table(pkg.filepath.read_text(encoding="utf-8")).items():
            if name not in pkg.members:
                target = pkg.path + module if module.startswith(".") else module
                pkg.set_member(name, griffe.Alias(name, f"{target}.{name}", parent=pkg))

    def _mark(self, module: griffe.Module, prefix: str) -> None:
        for name, member in module.members.items():
            if isinstance(member, griffe.Alias):
                if not name.startswith("_") and member.target_path.startswith(prefix):
                    member.public = True
                    try:  # a function re-exported under its module's name hides the module
                        _document_jitted(member.final_target)
                    except griffe.AliasResolutionError:
                        pass
            elif isinstance(member, griffe.Module):
                self._mark(member, prefix)
            else:
                _document_jitted(member)

def _document_jitted(member) -> None:
    """A compiled entry point (``joint_errors = eqx.filter_jit(joint_errors_traced)``) takes the
    docstring of the function it compiles."""
    if not isinstance(member, griffe.Attribute) or member.docstring is not None:
        return
    match = _JITTED.search(str(member.value or ""))
    wrapped = member.parent.members.get(match.group(1)) if match else None
    if wrapped is not None and not wrapped.is_alias and wrapped.docstring:
        member.docstring = griffe.Docstring(
            wrapped.docstring.value, lineno=wrapped.docstring.lineno, parent=member
        )


def _lazy_table(source: str) -> dict[str, str]:
    """The literal ``_LAZY = {...}`` table of a module's source, or ``{}``."""
    for node in ast.parse(source).body:
        targets = node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
        if any(getattr(t, "id", None) == "_LAZY" for t in targets):
            return ast.literal_eval(node.value)
    return {}
