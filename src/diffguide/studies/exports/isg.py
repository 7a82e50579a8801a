"""ISG kernel (Beckhoff TwinCAT CNC) volumetric compensation: the component errors of X in the
ISG CSV format, the configuration lines that assign and place the axes, and the start-up list
lines that load them.

Sources: Beckhoff Information System, TF5280 TwinCAT 3 CNC Volumetric Compensation: "ISG CSV
format" (header naming the argument and the parameters, records below, ``//`` line comments,
``#`` a file break), "Units of measure" (parameter values in mm and rad, the argument X in
mm), "List of parameters supported" (EXX ... ECX), "General configuration (obligatory)" (the
axis assignment by logical axis number, which must match the axes as measured; the bound on the
number of records in the start-up list); the compensation parameters P-VOLC-00001..00003 ``x``,
``y``, ``z`` (logical axis numbers of the ISO 230 X, Y, Z axes; no default), P-VOLC-00007
``chain`` (order of the axes in the kinematic chain, default ``XYZ``) and P-VOLC-00008
``workpiece_axes`` (how many axes of the chain lie on the workpiece side; default 0: all on the
tool side), with the rule of thumb that an axis the metrologist treated as workpiece-side is
configured so; the universal kinematics' chain runs from the workpiece to the tool, so the
workpiece axes come first; the start-up parameters P-STUP-00100 ``vol_comp[i].max_records``
(upper bound of the records read; default 0) and P-STUP-00101 ``vol_comp[i].file_name`` (the
configuration list).

The file holds the *errors* (the ISG model computes the correction, given the sides), which is
why it needs ``workpiece_axes``: X carries the workpiece in diffguide's model, so X is first
in the chain and counts as a workpiece axis.
"""

import numpy as np

from ._common import ISG_COMMENT, LIS_COMMENT, header_lines, sides


def _axis_lines(numbers) -> list[str]:
    """P-VOLC-00001..3: ``x N`` per axis whose logical number is given, else a comment."""
    lines, missing = [], []
    for axis in ("X", "Y", "Z"):
        if numbers and axis in numbers:
            lines.append(f"{axis.lower():<17}{numbers[axis]}")
        else:
            missing.append(axis)
    if missing:
        lines += LIS_COMMENT.lines([
            f"the logical axis number of {', '.join(missing)} was not given (CLI "
            "--isg-axis-numbers X=N,Y=N,Z=N, machine file [export] isg_axis_numbers): add "
            "the line(s) " + ", ".join(f"'{a.lower()} N'" for a in missing) + " (P-VOLC-0000"
            + "/".join(str("XYZ".index(a) + 1) for a in missing) + "; no default: the "
            "numbers of the axes as they were measured)"])
    return lines


def config(known, file_name="", numbers=None) -> str:
    """The volumetric compensation configuration lines (``#`` comments) for these sides and
    logical axis numbers."""
    lines = LIS_COMMENT.lines([
        "diffguide: configuration lines for the ISG volumetric compensation (TF5280)",
        "X carries the workpiece (diffguide's table), so it comes first in the chain"])
    lines += _axis_lines(numbers)
    if len(known) < 2:
        lines += LIS_COMMENT.lines([
            "the side of Y and/or Z was not given (axis_side, CLI --axis-side): set "
            "workpiece_axes to 1 + the number of Y, Z axes on the workpiece side",
            "chain XYZ", "workpiece_axes ?"])
    else:
        wp = [a for a in ("Y", "Z") if known[a] == "workpiece"]
        tool = [a for a in ("Y", "Z") if known[a] == "tool"]
        lines += [f"chain            X{''.join(wp)}{''.join(tool)}",
                  f"workpiece_axes   {1 + len(wp)}"]
    lines += [f"file[0]          {file_name or 'FILE.csv'}", "file_format[0]   ISG_CSV"]
    lines += LIS_COMMENT.lines(["the start-up list loads this list and bounds its records: "
                                "see the .startup.lis lines (vol_comp[0].file_name, "
                                "vol_comp[0].max_records)"])
    return "\n".join(lines) + "\n"


def startup(file_name, n_records: int, max_records=None) -> str:
    """The start-up list (``hochlauf.lis``) lines of compensation 0: its configuration list and
    the bound on the records (P-STUP-00101, P-STUP-00100; default 0, so it must be set)."""
    if max_records is not None and max_records < n_records:
        raise ValueError(f"isg: max_records (CLI --isg-max-records, [export] isg_max_records) "
                         f"{max_records} is less than the table's {n_records} records")
    lis = (file_name.rsplit(".", 1)[0] if file_name else "FILE") + ".lis"
    lines = LIS_COMMENT.lines([
        "diffguide: start-up list lines (hochlauf.lis) of volumetric compensation 0",
        f"the table has {n_records} records; max_records bounds the records of all the "
        "compensation's files (raise it where other files are added)"])
    lines += [f"vol_comp[0].file_name      {lis}",
              f"vol_comp[0].max_records    {max_records or n_records}"]
    return "\n".join(lines) + "\n"


def write(x_mm, err, *, x0_mm, point, source, spec, exx_includes_lead,
          straightness_note=None) -> dict[str, str]:
    known = sides(spec.axis_side)
    head = header_lines(point, source, x0_mm, "values: ISO 230-1 component errors of the X "
                        "axis (not negated: the controller compensates them); X carries the "
                        "workpiece: workpiece_axes must count it (see the .lis lines)",
                        exx_includes_lead, straightness_note)
    head.append("units: X, EXX, EYX, EZX in mm; EAX, EBX, ECX in rad")
    lis = config(known, spec.file_name, spec.isg_axis_numbers)
    boot = startup(spec.file_name, len(x_mm), spec.max_records)
    head += [f"config: {line}" for line in lis.splitlines() if not line.startswith("#")]
    head += [f"start-up: {line}" for line in boot.splitlines() if not line.startswith("#")]
    names = ["EXX", "EYX", "EZX", "EAX", "EBX", "ECX"]
    keep = [k for k in range(6) if k > 0 or exx_includes_lead is not None]
    lines = ISG_COMMENT.lines(head) + [" ".join(["X"] + [names[k] for k in keep])]
    for i, x in enumerate(np.asarray(x_mm)):
        vals = [f"{err[i, k] * 1e3:.9f}" if k < 3 else f"{err[i, k]:.12f}" for k in keep]
        lines.append(f"{x + x0_mm:.4f} " + " ".join(vals))
    return {"": "\n".join(lines) + "\n", ".lis": lis, ".startup.lis": boot}
