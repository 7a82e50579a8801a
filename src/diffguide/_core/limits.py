"""The sizes diffguide accepts, each refused (``ValueError`` naming the option or file, the
value and the allowed range) before anything of that size is allocated: an option or a file
that asks for more would otherwise run the machine out of memory, or stop with a traceback
after minutes. Each limit is far above real use; the reasoning is beside it."""

#: Table positions of one sweep (``simulate --positions``, ``predict --positions-mm`` or a
#: positions file, ``montecarlo``/``tolerance``/``design --positions``). Measured: a
#: ``simulate`` sweep holds ~10 kB per position (the solver's states, the errors, the CSV text)
#: and takes ~20 ms per position on a small machine, so 100 000 positions are ~1 GB and ~30
#: min; a measured or compensated axis has 10² to 10⁴ positions.
MAX_POSITIONS = 100_000

#: ``predict``: positions × points. The σ needs the Jacobian of the six errors in every
#: unknown of the fit (rails, structure, nuisances: a few hundred), 6 × n_unknowns × 8 bytes
#: per position and point, three times (the sweep's, the assembled one, the tool point's): at
#: most this in all (10 000 positions × 5 points with 250 unknowns are 1.8 GB).
MAX_PREDICTION_BYTES = 2 * 2**30

#: Table mesh divisions along X and along Y (``--mesh``, a machine file's ``[table] nx, ny``, a
#: fit's ``posterior.json``). The dense condensation of an ``nx × ny`` plate holds matrices
#: of its ~6·nx·ny DOF; 200 × 200 is already 200 times finer than the default 20 × 10.
MAX_MESH_DIVISIONS = 200

#: Retained DOF of an imported reduced matrix (a dense ``n × n`` float64 array, and a few of
#: its size in the condensation): 5 000 DOF are 200 MB each. A table reduced to its carriages,
#: nut and control points (the purpose of the import) retains a few hundred.
MAX_REDUCED_DOFS = 5_000

#: Random rail pairs of one study (``montecarlo``/``tolerance``/``design --samples``). Measured:
#: a sample holds ~4 kB at the default correlation length (its rails' coefficients, its
#: statistics and its CSV row), so 10⁶ samples are ~4 GB, and take hours.
MAX_SAMPLES = 1_000_000

#: A random-rails study's rails (two planes × two rails × the knots' coefficients × 8 bytes per
#: sample, more knots for a short correlation length) and results: at most this in all.
MAX_STUDY_BYTES = 8 * 2**30


def check_range(value, lo: int, hi: int, what: str, why: str = "") -> int:
    """``value`` where it is an integer in ``lo..hi``, else ``ValueError`` naming ``what``, the
    value and the range (and ``why``, where given)."""
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ValueError(f"{what} must be in {lo}..{hi}{'; ' + why if why else ''}, got "
                         f"{value!r}")
    return value


def gigabytes(n_bytes: float) -> str:
    """``n_bytes`` as ``"1.2 GB"``."""
    return f"{n_bytes / 1e9:.3g} GB"
