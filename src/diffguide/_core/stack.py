"""The numerical stack: which JAX versions are known to misbehave here, and a clear warning.

jax/jaxlib 0.10.2 deadlocked on a 2-core CPU and, through the hand-written implicit solve of
this package, returned a wrong ``jax.jacfwd`` in about one of four fresh compilations (silently:
a wrong fit Jacobian, so a wrong fit); 0.9.2 was clean. ``tests/test_stack.py`` compiles the fit
Jacobian in two fresh processes and compares them. Set ``DIFFGUIDE_ALLOW_BAD_JAX=1`` to silence
the warning (e.g. to test a fix).
"""

import os
import warnings
from importlib.metadata import PackageNotFoundError, version

#: (distribution, version) -> what goes wrong
_PROBLEM = (
    "was seen to deadlock on a 2-core CPU and to return wrong jacfwd results through implicit "
    "solves in ~1 of 4 fresh compilations (intermittent: a later matrix run passed)"
)
KNOWN_BAD = {("jax", "0.10.2"): _PROBLEM, ("jaxlib", "0.10.2"): _PROBLEM}

_warned = False


def installed_versions() -> dict[str, str]:
    out = {}
    for dist in ("jax", "jaxlib"):
        try:
            out[dist] = version(dist)
        except PackageNotFoundError:
            pass
    return out


def known_problems(versions: dict[str, str]) -> list[str]:
    """One sentence per known-bad distribution in ``versions`` (``{"jax": "0.10.2", ...}``)."""
    return [
        f"{dist} {v} {KNOWN_BAD[dist, v]}; diffguide's full suite runs on jax/jaxlib 0.9.2 "
        f"(pip install 'diffguide[pinned]'); DIFFGUIDE_ALLOW_BAD_JAX=1 silences this"
        for dist, v in versions.items()
        if (dist, v) in KNOWN_BAD
    ]


def check_stack() -> None:
    """Warn (``RuntimeWarning``, once per process) when a known-bad JAX is installed."""
    global _warned
    if _warned or os.environ.get("DIFFGUIDE_ALLOW_BAD_JAX"):
        return
    _warned = True
    for text in known_problems(installed_versions()):
        warnings.warn(text, RuntimeWarning, stacklevel=3)
