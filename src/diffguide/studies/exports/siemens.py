"""SINUMERIK 840D sl sag compensation (CEC) init program for EYX on Y and EZX on Z.

Syntax and activation from the SINUMERIK function manual *Extended Functions*, K3
"Compensations", section 4.4.3 "Compensation of sag and angularity errors", edition 03/2013
(6FC5397-1BP40-3BA1), pp. 243–250 and the example on p. 264; the same program frame in the
802D sl function manual 11/2012 (6FC5397-1CP10-5BA0), p. 222:

- an init program ``%_N_NC_CEC_INI`` / ``CHANDATA(1)`` ... ``M17``, ``;`` comments;
- per table ``t``: ``$AN_CEC[t,N]`` (compensation value of interpolation point N of the
  compensation axis, mm), ``$AN_CEC_INPUT_AXIS[t]`` (basic axis), ``$AN_CEC_OUTPUT_AXIS[t]``
  (compensation axis), ``$AN_CEC_STEP[t]`` (distance of the points), ``$AN_CEC_MIN[t]`` (position
  of point 0), ``$AN_CEC_MAX[t]`` (position of the last point), ``$AN_CEC_DIRECTION[t]`` (0: both
  directions), ``$AN_CEC_MULT_BY_TABLE[t]`` (0: none), ``$AN_CEC_IS_MODULO[t]`` (0: none);
- activation: MD18342 ``$MN_MM_CEC_MAX_POINTS[t]`` reserves the points (the memory is
  re-formatted at the next power-on), the tables load only while MD32710
  ``$MA_CEC_ENABLE[axis]`` = 0 (p. 237), then MD32710 = 1 for the compensation axis and SD41300
  ``$SN_CEC_TABLE_ENABLE[t]`` = 1 per table (p. 245).

The compensation values are ``sign × error`` (:mod:`._common`: the side of the compensation
axis); EXX (pitch) belongs to the separate LEC tables (``$AA_ENC_COMP``) and is not written.
"""

import numpy as np

from ._common import CEC_COMMENT, cross_tables, equidistant_step, header_lines


def activation_block(tables, names, n) -> list[str]:
    """The machine and setting data that make the tables act (commented: they are not part
    of an init program)."""
    out = ["--- activation (machine/setting data, not part of this program; K3 4.4.3) ---"]
    for t in range(len(tables)):
        out.append(f"MD18342 $MN_MM_CEC_MAX_POINTS[{t}] >= {n}  (then power on: the static "
                   "memory is re-formatted; back it up first)")
    axes = ", ".join(f"[{names[axis]}]" for _, axis, _, _ in tables)
    out += [
        f"MD32710 $MA_CEC_ENABLE{axes} = 0 while this program is loaded (tables load only "
        "when it is 0)",
        f"then MD32710 $MA_CEC_ENABLE{axes} = 1 and NEWCONF",
    ]
    out += [f"SD41300 $SN_CEC_TABLE_ENABLE[{t}] = 1" for t in range(len(tables))]
    out.append("the basic axis must be referenced for the compensation to act")
    return CEC_COMMENT.lines(out)


def write(x_mm, err, *, x0_mm, point, source, spec, exx_includes_lead,
          straightness_note=None) -> dict[str, str]:
    step = equidistant_step(x_mm, "siemens-cec")
    tables = cross_tables(err, spec.axis_side, "siemens-cec")
    names = spec.axis_names
    head = header_lines(point, source, x0_mm, "values: compensation values of the "
                        "compensation axis, mm (sign from the side of that axis)",
                        exx_includes_lead, straightness_note)
    head[3] = "EXX (pitch) is not in this program: it belongs to the LEC tables ($AA_ENC_COMP)"
    head.append("machine axis names (MD10000 $MN_AXCONF_MACHAX_NAME_TAB of your machine; CLI "
                "--cec-axis-names, [export] cec_axis_names): "
                + ", ".join(f"{a}={names[a]}" for a in ("X", "Y", "Z")))
    out = ["%_N_NC_CEC_INI", "CHANDATA(1)"] + CEC_COMMENT.lines(head)
    out += activation_block(tables, names, len(x_mm))
    for t, (name, axis, side, comp) in enumerate(tables):
        out += CEC_COMMENT.lines([f"table {t}: {'+' if side == 'tool' else '-'}{name} on "
                                  f"{names[axis]} ({axis}, {side} side) as a function of "
                                  f"{names['X']} (X)"])
        out += [f"$AN_CEC[{t},{i}]={v * 1e3:.6f}" for i, v in enumerate(np.asarray(comp))]
        out += [
            f"$AN_CEC_INPUT_AXIS[{t}]=({names['X']})",
            f"$AN_CEC_OUTPUT_AXIS[{t}]=({names[axis]})",
            f"$AN_CEC_STEP[{t}]={step:.4f}",
            f"$AN_CEC_MIN[{t}]={x_mm[0] + x0_mm:.4f}",
            f"$AN_CEC_MAX[{t}]={x_mm[-1] + x0_mm:.4f}",
            f"$AN_CEC_DIRECTION[{t}]=0",
            f"$AN_CEC_MULT_BY_TABLE[{t}]=0",
            f"$AN_CEC_IS_MODULO[{t}]=0",
        ]
    out.append("M17")
    return {"": "\n".join(out) + "\n"}
