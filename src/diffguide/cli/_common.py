"""Arguments shared by the commands: the machine (``--preset`` / ``--config``)."""

PRESETS = ("majda2012",)


def add_machine_arguments(p) -> None:
    p.add_argument("--preset", default="majda2012", choices=PRESETS,
                   help="built-in machine (the paper's vertical machining centre)")
    p.add_argument("--config", metavar="MACHINE.toml",
                   help="machine configuration file (TOML, units in the key names; see "
                   "'diffguide config'); overrides --preset")


def machine_config(args) -> dict:
    """The validated configuration chosen by ``--config`` or ``--preset``."""
    from ..io.config import default_config, load_config

    if getattr(args, "config", None):
        return load_config(args.config)
    return default_config()
