"""diffguide's own CSV: the errors (not negated) and their σ, ``#`` comment lines first."""

from ...machine.kinematics import ERROR_NAMES
from ._common import CSV_COMMENT, header_lines

UNITS = ("um", "um", "um", "urad", "urad", "urad")


def sigma_csv(x_mm, sigma, x0_mm, point, exx_includes_lead=True, straightness_note=None) -> str:
    """The companion file: ``X_machine_mm,x_mm`` and the six σ (µm, µrad), standard
    uncertainties of the *errors* (the same for the compensation values); EXX's empty where
    EXX is left out."""
    lines = [
        *CSV_COMMENT.lines([f"diffguide: standard uncertainty (1 sigma) of the errors at "
                            f"point {point}", *(straightness_note or ())]),
        "X_machine_mm,x_mm," + ",".join(f"{n}_sigma_{u}" for n, u in zip(ERROR_NAMES, UNITS)),
    ]
    for x, s in zip(x_mm, sigma):
        vals = [f"{v * 1e6:.5f}" for v in s]
        if exx_includes_lead is None:
            vals[0] = ""
        lines.append(f"{x + x0_mm:.4f},{x:.4f}," + ",".join(vals))
    return "\n".join(lines) + "\n"


def write(x_mm, err, sig, *, x0_mm, point, source, exx_includes_lead,
          straightness_note=None) -> dict[str, str]:
    head = header_lines(point, source, x0_mm, "values: the errors (ISO 230-1 signs, relative "
                        "to x = 0); a controller compensates them (sign by the side of the "
                        "compensating axis)", exx_includes_lead, straightness_note)
    cols = ["X_machine_mm", "x_mm"]
    for n, u in zip(ERROR_NAMES, UNITS):
        cols += [f"{n}_{u}", f"{n}_sigma_{u}"]
    lines = CSV_COMMENT.lines(head) + [",".join(cols)]
    for i, x in enumerate(x_mm):
        vals = []
        for k in range(6):
            if k == 0 and exx_includes_lead is None:
                vals += ["", ""]
                continue
            vals += [f"{err[i, k] * 1e6:.5f}", "" if sig is None else f"{sig[i, k] * 1e6:.5f}"]
        lines.append(f"{x + x0_mm:.4f},{x:.4f}," + ",".join(vals))
    return {"": "\n".join(lines) + "\n"}
