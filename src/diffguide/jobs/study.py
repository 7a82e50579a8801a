"""The random-rails study's settings shared by the ``montecarlo``, ``tolerance`` and
``design`` jobs: the rail model (RMS, correlation length, kernel, planes, mounting), the sweep
(positions, mesh, rigid table), the batching and the seed; their checks, and the machine,
positions, model and spline knots they give (:func:`study_setup`). Nothing heavy imported."""

import math

from .positions import stroke_positions

#: ``--kernel`` -> the covariance of :class:`diffguide.studies.random_rails.GaussianRailModel`
KERNELS = {"se": "squared_exponential", "matern52": "matern52"}
#: ``--planes`` -> the planes with straightness error
PLANES = {"both": ("vertical", "horizontal"), "vertical": ("vertical",),
          "horizontal": ("horizontal",)}
#: the mounting classes of rail 2 (``diffguide.studies.random_rails.MOUNTING_CLASSES``, named
#: here so that the settings import no JAX; tests/test_cli_common.py checks they agree)
MOUNTING_CHOICES = ("none", "precision", "size25-ZB", "size25-ZA", "size25-ZO")


def check_study(s) -> None:
    """Range checks of the study's options (any object with their attributes: settings or the
    command line's namespace); ``ValueError`` naming the option."""
    if not (math.isfinite(s.corr_mm) and 1 <= s.corr_mm <= 1e5):
        raise ValueError(f"--corr-mm must be in 1..100000 mm, got {s.corr_mm}")
    if s.chunk is not None and not 1 <= s.chunk <= 100_000:
        raise ValueError(f"--chunk must be in 1..100000, got {s.chunk}")
    if s.cpu_devices is not None and not 1 <= s.cpu_devices <= 256:
        raise ValueError(f"--cpu-devices must be in 1..256, got {s.cpu_devices}")
    for name, table in (("kernel", KERNELS), ("planes", PLANES)):
        if getattr(s, name) not in table:
            raise ValueError(f"--{name} must be one of {', '.join(table)}, got "
                             f"{getattr(s, name)!r}")
    if s.mounting not in MOUNTING_CHOICES:
        raise ValueError(f"--mounting must be one of {', '.join(MOUNTING_CHOICES)}, got "
                         f"{s.mounting!r}")


def check_size(n: int, n_coeffs: int, corr_mm: float) -> None:
    """Refuse a study whose rails and results would exceed ``MAX_STUDY_BYTES``, before they are
    drawn (a short correlation length needs more spline coefficients per rail)."""
    from .._core.limits import MAX_STUDY_BYTES, gigabytes
    from ..studies.random_rails import study_bytes

    need = study_bytes(n, n_coeffs)
    if need > MAX_STUDY_BYTES:
        most = MAX_STUDY_BYTES // study_bytes(1, n_coeffs)
        raise ValueError(f"--samples {n} with --corr-mm {corr_mm:g} (rails of {n_coeffs} spline "
                         f"coefficients per rail and plane) need about {gigabytes(need)}; allowed "
                         f"up to {most} samples at this --corr-mm ({gigabytes(MAX_STUDY_BYTES)})")


def machine_config(s) -> dict:
    """The validated configuration of ``s.config`` (a machine file), else the preset's."""
    from ..io.config import default_config, load_config

    return load_config(s.config) if getattr(s, "config", None) else default_config()


def study_setup(s, rms: float, say, n_samples: int):
    """The machine, positions (m), rail model (RMS ``rms``, m) and knots of a random-rails
    study ``s`` (its ``n_samples`` checked against the memory limit): ``(name, machine,
    positions, model, knots)``; ``say`` receives the progress line."""
    from ..inverse.fit import visited_range
    from .machine import config_machine
    from ..studies.random_rails import GaussianRailModel, default_knots

    cfg = machine_config(s)
    name = s.config or s.preset
    positions = stroke_positions(cfg, s.positions, name)
    model = GaussianRailModel(rms, s.corr_mm * 1e-3, KERNELS[s.kernel], PLANES[s.planes])
    if cfg.get("table_source"):
        say(f"building the {name} machine (table imported from "
            f"{cfg['table_source']['given']}) ...")
    else:
        say(f"building the {name} machine (table mesh {s.mesh or 'of the machine file'}) ...")
    machine = config_machine(cfg, nx=s.nx, ny=s.ny)  # --mesh on an imported table: refused
    # the rails must cover what the elements visit: the default ±0.6 m knots (majda2012) or,
    # for a longer machine, the visited range with a margin
    lo, hi = visited_range(machine, positions)
    knots = default_knots(model.correlation_length)
    if lo < knots[0] or hi > knots[0] + (knots[2] - 3) * knots[1]:
        knots = default_knots(model.correlation_length, start=lo - 0.05, end=hi + 0.05)
    check_size(n_samples, knots[2], s.corr_mm)
    if s.rigid_table:
        machine = machine.with_rigid_table()
    return name, machine, positions, model, knots
