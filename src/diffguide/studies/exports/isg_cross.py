"""ISG kernel (Beckhoff TwinCAT CNC) cross compensation ("Kreuzkompensation", also called sag
compensation): EYX on Y and EZX on Z as functions of the command position of X, one axis
compensation list per compensated (slave) axis.

Sources: Beckhoff Information System, TF5200 TwinCAT 3 CNC Axis compensation (and the ISG
kernel documentation, isg-stuttgart.de): "Cross compensation (kw.crosscomp.*)", "The
compensation list header (kopf.*)", "Example of a compensation value list" (a Z-axis list with
X as master), "Overview of compensation parameters", and the parameters

- P-COMP-00001 ``kopf.achs_nr``: logical axis number of the list's axis (0 not allowed);
  P-COMP-00002 ``kopf.log_achs_name``: its name;
- P-COMP-00003 ``kw.crosscomp.unit``: 1 = metric, in 0.1 µm (0: encoder increments);
- P-COMP-00004 ``kw.crosscomp.last_index``: last valid index (the table starts at 0);
- P-COMP-00005 ``kw.crosscomp.master_ax_nr``: logical axis number of the master axis, whose
  command position is the table's input;
- P-COMP-00006 ``kw.crosscomp.table[i].setpoint``: interpolation points of the master axis
  (absolute command positions, 0.1 µm);
- P-COMP-00007 ``kw.crosscomp.table[i].correction``: the relative compensation values of the
  slave axis (0.1 µm; an integer SGN32 before CNC build V3.1.3132.0, REAL64 since);
- P-COMP-00060 ``kw.crosscomp.max_points``: memory for the table (default 1001; ``last_index``
  must stay below it);
- P-AXIS-00047 ``lr_param.crosscomp`` = 1 in the slave axis' machine data activates it; it
  acts once the master axis is referenced.

The list is the slave axis': its header names the slave (``kopf.achs_nr``) and its body the
master (``master_ax_nr``), as in the documented example (one overview page says the data sit in
the master axis' list; the example and the parameters read the other way). Lines ``name
value``, ``#`` comment lines and ``/* ... */`` comments.

**Sign: unconfirmed.** The pages read call the values "relative compensation values" of the
slave axis without saying whether the kernel adds or subtracts them; by default they are the
compensation ``C = sign × E`` (:mod:`._common`: the side of the slave axis) that the axis
adds, and ``isg_cross_values = "error"`` writes ``−C``. The header says which.
"""

import numpy as np

from ._common import (
    LIS_COMMENT,
    cross_tables,
    equidistant_step,
    header_lines,
    value_sign,
    values_line,
)

TENTH_UM = 1e-7  # m: the metric unit of the list (kw.crosscomp.unit = 1)
DEFAULT_MAX_POINTS = 1001  # P-COMP-00060's default


def _numbers(spec, axes) -> dict[str, int]:
    numbers = dict(spec.isg_axis_numbers or {})
    missing = [a for a in ("X", *axes) if a not in numbers]
    if missing:
        raise ValueError(
            f"isg-cross: the logical axis number of {', '.join(missing)} is needed (the list's "
            "kopf.achs_nr and kw.crosscomp.master_ax_nr); give --isg-axis-numbers X=N,Y=N,Z=N "
            "(machine file: [export] isg_axis_numbers = {X = 1, Y = 2, Z = 3})")
    return numbers


def axis_list(axis, comp, X, numbers, head) -> str:
    """The compensation list of slave ``axis``: ``comp`` (m) the values at master positions
    ``X`` (mm)."""
    n = len(X)
    setpoint = np.round(np.asarray(X) * 1e-3 / TENTH_UM).astype(np.int64)
    correction = np.round(np.asarray(comp) / TENTH_UM).astype(np.int64)
    lines = LIS_COMMENT.lines(head)
    lines += [f"kopf.achs_nr                  {numbers[axis]}",
              f"kopf.log_achs_name            {axis}",
              f"kw.crosscomp.last_index       {n - 1}",
              f"kw.crosscomp.master_ax_nr     {numbers['X']}",
              "kw.crosscomp.unit             1   /* metric, 0.1 um */"]
    if n >= DEFAULT_MAX_POINTS:
        lines.append(f"kw.crosscomp.max_points       {n + 1}   /* last_index < max_points */")
    for i in range(n):
        lines += [f"kw.crosscomp.table[{i}].setpoint     {setpoint[i]}",
                  f"kw.crosscomp.table[{i}].correction   {correction[i]}"]
    return "\n".join(lines) + "\n"


def write(x_mm, err, *, x0_mm, point, source, spec, exx_includes_lead,
          straightness_note=None) -> dict[str, str]:
    equidistant_step(x_mm, "isg-cross")  # increasing setpoints, at least two
    tables = cross_tables(err, spec.axis_side, "isg-cross")
    numbers = _numbers(spec, [axis for _, axis, _, _ in tables])
    X = np.asarray(x_mm) + x0_mm
    k = value_sign(spec.isg_cross_values)
    files, notes = {}, []
    stem = spec.file_name.rsplit(".", 1)[0] if spec.file_name else "FILE"
    base = header_lines(point, source, x0_mm, values_line(
        spec.isg_cross_values, "ISG cross compensation", "isg_cross_values"),
        exx_includes_lead, straightness_note)
    base[3] = ("EXX (pitch) is not in these lists: it belongs to the leadscrew error "
               "compensation (kw.ssfk); angles EAX, EBX, ECX neither (cross compensation "
               "moves axes only)")
    for name, axis, side, comp in tables:
        head = base + [f"axis compensation list of {axis} (logical axis {numbers[axis]}): "
                       f"{'+' if side == 'tool' else '-'}{name} ({axis} on the {side} side) "
                       f"as a function of the command position of X (logical axis "
                       f"{numbers['X']}); positions and values in 0.1 um"]
        files[f".{axis}.lis"] = axis_list(axis, k * comp, X, numbers, head)
        notes.append(f"{axis}: the list {stem}.{axis}.lis as the axis compensation list of "
                     f"logical axis {numbers[axis]}, and lr_param.crosscomp 1 (P-AXIS-00047) "
                     f"in its axis machine data")
    overview = base + [
        "ISG cross compensation: one axis compensation list per compensated axis",
        *notes,
        "enter each list for its axis in the start-up list; cross compensation acts once "
        "X is referenced",
        f"{len(X)} points per table"
        + (f": set kw.crosscomp.max_points (P-COMP-00060) > {len(X) - 1} (written in the "
           "lists)" if len(X) >= DEFAULT_MAX_POINTS else
           " (the default kw.crosscomp.max_points 1001 holds them)")]
    files[""] = "\n".join(LIS_COMMENT.lines(overview)) + "\n"
    return {"": files.pop(""), **files}
