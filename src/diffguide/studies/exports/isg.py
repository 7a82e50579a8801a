"""ISG kernel (Beckhoff TwinCAT CNC) volumetric compensation: the component errors of X in the
ISG CSV format, and the configuration lines that state the side of each axis.

Sources: Beckhoff Information System, TF5280 TwinCAT 3 CNC Volumetric Compensation: "ISG CSV
format" (header naming the argument and the parameters, records below, ``//`` line comments,
``#`` a file break), "Units of measure" (parameter values in mm and rad, the argument X in
mm), "List of parameters supported" (EXX ... ECX); the compensation parameters P-VOLC-00007
``chain`` (order of the axes in the kinematic chain, default ``XYZ``) and P-VOLC-00008
``workpiece_axes`` (how many axes of the chain lie on the workpiece side; default 0: all on the
tool side), with the rule of thumb that an axis the metrologist treated as workpiece-side is
configured so; the universal kinematics' chain runs from the workpiece to the tool, so the
workpiece axes come first.

The file holds the *errors* (the ISG model computes the correction, given the sides), which is
why it needs ``workpiece_axes``: X carries the workpiece in diffguide's model, so X is first
in the chain and counts as a workpiece axis.
"""

import numpy as np

from ._common import ISG_COMMENT, LIS_COMMENT, header_lines, sides


def config(known, file_name="") -> str:
    """The volumetric compensation configuration lines (``#`` comments) for these sides."""
    lines = LIS_COMMENT.lines([
        "diffguide: configuration lines for the ISG volumetric compensation (TF5280)",
        "X carries the workpiece (diffguide's table), so it comes first in the chain"])
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
    return "\n".join(lines) + "\n"


def write(x_mm, err, *, x0_mm, point, source, spec, exx_includes_lead) -> dict[str, str]:
    known = sides(spec.axis_side)
    head = header_lines(point, source, x0_mm, "values: ISO 230-1 component errors of the X "
                        "axis (not negated: the controller compensates them); X carries the "
                        "workpiece: workpiece_axes must count it (see the .lis lines)",
                        exx_includes_lead)
    head.append("units: X, EXX, EYX, EZX in mm; EAX, EBX, ECX in rad")
    head += [f"config: {line}" for line in config(known, spec.file_name).splitlines() if not
             line.startswith("#")]
    names = ["EXX", "EYX", "EZX", "EAX", "EBX", "ECX"]
    keep = [k for k in range(6) if k > 0 or exx_includes_lead is not None]
    lines = ISG_COMMENT.lines(head) + [" ".join(["X"] + [names[k] for k in keep])]
    for i, x in enumerate(np.asarray(x_mm)):
        vals = [f"{err[i, k] * 1e3:.9f}" if k < 3 else f"{err[i, k]:.12f}" for k in keep]
        lines.append(f"{x + x0_mm:.4f} " + " ".join(vals))
    return {"": "\n".join(lines) + "\n", ".lis": config(known, spec.file_name)}
