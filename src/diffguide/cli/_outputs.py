"""The commands' outputs checked before the work: each output's folder writable, with free
space (:func:`diffguide._core.atomic.check_output_place`), and the leftovers of killed runs
beside an output folder removed (:func:`diffguide._core.atomic.remove_leftovers`)."""

from .._core.atomic import MIN_FREE_BYTES, check_output_place, remove_leftovers

#: command -> the destinations (argparse ``dest``) of its output files and folders
OUTPUT_FILES = {
    "config": ("out",),
    "import": ("out",),
    "stiffness": ("out", "plot"),
    "table": ("out", "plot"),
    "simulate": ("out", "plot", "export_compensation", "field_plot"),
    "montecarlo": ("out", "plot"),
    "fit": ("export_compensation",),
    "predict": ("out",),
    "design": ("out", "json", "plot"),
}
#: command -> the destinations of its output folders (replaced whole)
OUTPUT_DIRS = {"fit": ("out",), "plan": ("out",)}


def check_outputs(args, command: str, need_bytes: int = MIN_FREE_BYTES) -> None:
    """Refuse (``ValueError`` naming the flag and the folder) an output that cannot be written;
    remove the leftovers of killed runs beside each output folder."""
    for kind, table in (("file", OUTPUT_FILES), ("dir", OUTPUT_DIRS)):
        for dest in table.get(command, ()):
            path = getattr(args, dest, None)
            if not path:
                continue
            flag = "--" + dest.replace("_", "-")
            try:
                check_output_place(path, need_bytes)
            except ValueError as exc:
                raise ValueError(f"{flag} {path}: {exc}; nothing done") from None
            if kind == "dir":
                remove_leftovers(path)
