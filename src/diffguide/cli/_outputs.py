"""The commands' outputs checked before the work: each output's folder writable, with free
space (:func:`diffguide._core.atomic.check_output_place`); an output file not a folder
(:func:`diffguide._core.atomic.check_output_file`); an output folder one that the command may
replace (:func:`diffguide.io.outdir.check_output_dir`: never the working folder, a parent of
it, or a folder diffguide did not write), and the leftovers of killed runs beside it removed
(:func:`diffguide._core.atomic.remove_leftovers`)."""

from pathlib import Path

from .._core.atomic import MIN_FREE_BYTES, check_output_file, check_output_place, remove_leftovers
from ._interrupt import checkpoint

#: command -> the destinations (argparse ``dest``) of its output files
OUTPUT_FILES = {
    "config": ("out",),
    "import": ("out",),
    "stiffness": ("out", "plot"),
    "table": ("out", "plot"),
    "simulate": ("out", "plot", "export_compensation", "field_plot"),
    "montecarlo": ("out", "plot"),
    "tolerance": ("out",),
    "fit": ("export_compensation",),
    "predict": ("out",),
    "design": ("out", "json", "plot"),
}
#: command -> the destinations of its output folders (replaced whole where diffguide wrote them)
OUTPUT_DIRS = {"fit": ("out",), "plan": ("out",)}


def check_outputs(args, command: str, need_bytes: int = MIN_FREE_BYTES) -> None:
    """Refuse (``ValueError`` naming the flag and the path) an output that cannot or may not be
    written; remove the leftovers of killed runs beside each output folder."""
    for kind, table in (("file", OUTPUT_FILES), ("dir", OUTPUT_DIRS)):
        for dest in table.get(command, ()):
            path = getattr(args, dest, None)
            if not path:
                continue
            flag = "--" + dest.replace("_", "-")
            if kind == "dir":
                from ..io.outdir import check_output_dir  # here: --help imports no JAX

                check_output_dir(path, command, flag)  # its own message, naming flag and path
            try:
                if kind == "file":
                    check_output_file(path)
                check_output_place(path, need_bytes)
            except ValueError as exc:
                raise ValueError(f"{flag} {path}: {exc}; nothing done") from None
            if kind == "dir":
                remove_leftovers(path)
    _check_files_outside_folders(args, command)


def _check_files_outside_folders(args, command: str) -> None:
    """An output file inside an output folder of the same command would be an unlisted file
    there (the folder is replaced whole, and then refused as holding a file diffguide did not
    write): refused before the work."""
    for dir_dest in OUTPUT_DIRS.get(command, ()):
        folder = getattr(args, dir_dest, None)
        if not folder:
            continue
        folder = Path(folder).resolve()
        for dest in OUTPUT_FILES.get(command, ()):
            path = getattr(args, dest, None)
            if path and folder in Path(path).resolve().parents:
                flag, dir_flag = "--" + dest.replace("_", "-"), "--" + dir_dest.replace("_", "-")
                raise ValueError(f"{flag} {path}: inside the output folder {dir_flag} "
                                 f"{getattr(args, dir_dest)}, which is replaced whole; write it "
                                 "elsewhere (nothing done)")


def output_folder(args, command: str):
    """``args.out`` as ``command``'s output folder, staged and committed at once
    (:class:`diffguide.io.outdir.OutputFolder`), stopped by a Ctrl-C before staging and
    before the swap (:func:`._interrupt.checkpoint`)."""
    from ..io.outdir import OutputFolder

    return OutputFolder(Path(args.out), command, "--out", checkpoint=checkpoint)


def write_dir(args, command: str, files: dict[str, object]) -> None:
    """Write ``files`` ({name: text or figure}) as ``command``'s output folder ``args.out``."""
    with output_folder(args, command) as staged:
        staged.write(files)
        staged.commit()
