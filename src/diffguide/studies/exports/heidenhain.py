"""HEIDENHAIN TNC nonlinear axis error compensation: a ``.COM`` table and its ``.CMA``.

Layout from the HEIDENHAIN *Technical Manual MANUALplus 620* (January 2012), section 6.10.3
"Nonlinear axis error compensation", pp. 713–718 (the TNC family shares the function; the
TNC 407 technical manual describes its ``.CMA``/``.COM`` pair the same way):

- a compensation-value table ``*.COM``: the ``AXISPOS`` column holds the compensation points
  (positions relative to the machine datum), and the compensation values go into the column
  named after the *compensated* axis (the axis key of ``CfgAxes/axisList``); an optional
  ``BACKLASH`` column is not written;
- an assignment table ``*.CMA`` (standard name ``config.cma``): one column per axis, holding in
  each line the ``.COM`` files; relationship: [axis of the ``.COM`` column] = F(axis of the
  ``.CMA`` column the ``.COM`` is entered in); ``*`` in the ``ACTIVE`` column selects the line.

So one ``NAME.COM`` with columns ``NR AXISPOS X Y Z`` entered in the ``X`` column of the
``.CMA`` compensates X (pitch, −EXX), Y and Z (``sign × EYX``, ``sign × EZX``) as functions
of X. Values and positions in mm.

**Experimental:** the table frame (``BEGIN NAME.COM MM`` / column line / rows / ``[END]``) is
that of the TNC's other tables; it could not be confirmed for ``.COM``/``.CMA`` from the
documentation read. Angles (EAX, EBX, ECX) are refused: nonlinear compensation moves axes only;
angular errors need the KinematicsComp option, whose ``.COM`` layout was not confirmed either.
"""

import numpy as np

from ._common import (
    CROSS_AXES,
    NOTE_TEXT,
    header_lines,
    lead_line,
    sides,
    sign,
    value_sign,
    values_line,
)

EXPERIMENTAL = ("the table frame BEGIN/[END] of .COM and .CMA is assumed from the TNC's other "
                "tables, not confirmed")


def _table(name, cols, rows, widths) -> str:
    lines = [name, "".join(c.ljust(w) for c, w in zip(cols, widths)).rstrip()]
    lines += ["".join(v.ljust(w) for v, w in zip(r, widths)).rstrip() for r in rows]
    return "\n".join(lines + ["[END]"]) + "\n"


def write(x_mm, err, *, x0_mm, point, source, spec, exx_includes_lead,
          straightness_note=None) -> dict[str, str]:
    known = sides(spec.axis_side)
    factor = value_sign(spec.heidenhain_values)  # C, or -C where the value is the error
    cols = {}  # compensated axis -> compensation (m)
    if exx_includes_lead is not None:
        cols["X"] = -err[:, 0]  # X carries the workpiece: C = -EXX
    for k, axis in enumerate(CROSS_AXES.values(), start=1):
        if axis in known:
            cols[axis] = sign(known[axis]) * err[:, k]
    if not cols:
        raise ValueError(
            "heidenhain: nothing to write: " + lead_line(None) + "; and the side of Y and Z is "
            "not given (axis_side, CLI --axis-side) for EYX/EZX")
    name = spec.table_name.upper()
    names = ["NR", "AXISPOS", *cols]  # the axis keys of CfgAxes/axisList (assumed X, Y, Z)
    rows = [[f"{i}", f"{x + x0_mm:+.4f}"]
            + [f"{factor * c[i] * 1e3:+.7f}" for c in cols.values()]
            for i, x in enumerate(np.asarray(x_mm))]
    com = _table(f"BEGIN {name}.COM MM", names, rows, [6, 14] + [14] * len(cols))
    cma = _table("BEGIN CONFIG.CMA", ["NR", "X", "ACTIVE"], [["0", f"{name}.COM", "*"]],
                 [6, 16, 8])
    head = header_lines(point, source, x0_mm, "values in mm: the compensation C of X = -EXX "
                        "(X carries the workpiece); of Y, Z = sign x EYX, EZX by their side",
                        exx_includes_lead,
                        straightness_note if set(cols) & {"Y", "Z"} else None)
    head += [values_line(spec.heidenhain_values, "HEIDENHAIN", "heidenhain_values"),
             f"EXPERIMENTAL: {EXPERIMENTAL}",
             f"sides: {', '.join(f'{a} {s}' for a, s in known.items()) or 'Y, Z not given'}; "
             "EYX/EZX of an axis whose side is not given are not written",
             "angles EAX, EBX, ECX are not written: nonlinear axis error compensation moves "
             "axes only (KinematicsComp needed)",
             f"save the table as {name}.COM and the assignment as CONFIG.CMA (or enter the line "
             "in the machine's .CMA); the TNC tables have no comment lines, hence this note"]
    return {"": com, ".cma": cma, ".note.txt": "\n".join(NOTE_TEXT.lines(head)) + "\n"}
