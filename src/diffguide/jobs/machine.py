"""The machine of a configuration file (:func:`diffguide.io.config.load_config`), whichever the
table's source: diffguide's plate or an imported (superelement) table read with the file
(:mod:`diffguide.io.table_source`); the building itself is
:func:`diffguide.machine.imported.machine_of_source`."""


def config_machine(cfg: dict, *, nx: int | None = None, ny: int | None = None,
                   points: dict | None = None, stiffness_scale=None, **overrides):
    """The :class:`~diffguide.machine.Machine` of a validated configuration, whichever the
    table's source.

    Arguments:
        cfg: the configuration (:func:`diffguide.io.config.load_config`).
        nx, ny: the plate's mesh (``None``: the file's); refused for an imported table.
        points: control points ``{name: (x, y)}`` (m) in place of the file's; for an imported
            table each must be a retained node of the description file.
        stiffness_scale: a factor on an imported table's stiffness (may be traced;
            :func:`~diffguide.fe.superelement.scaled_table`); refused for the plate.
        overrides: :func:`~diffguide.machine.build.build_machine`'s (``thickness``,
            ``preload_fraction``, …; SI); an imported table takes ``preload_fraction`` only.
    """
    from ..io.config_spec import spec_from_config
    from ..machine.imported import machine_of_source

    src = cfg.get("table_source")
    return machine_of_source(spec_from_config(cfg), src and src["table"],
                             source=src["given"] if src else "", nx=nx, ny=ny, points=points,
                             stiffness_scale=stiffness_scale, **overrides)


def machine_builder(cfg: dict, nx: int | None = None, ny: int | None = None):
    """``make_machine(points, **kw)`` for :func:`diffguide.inverse.predict.predict`: the
    configuration's machine with ``points`` and the fitted structure (:func:`config_machine`);
    ``None`` for the plate (predict's own builder)."""
    if cfg.get("table_source") is None:
        return None
    return lambda points, **kw: config_machine(cfg, nx=nx, ny=ny, points=points, **kw)
