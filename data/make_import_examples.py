r"""Make the example files of the import layouts from the bundled data set.

Every file holds exactly the readings of ``majda2012_measurements.csv`` (the canonical long
layout), written as instrument software would, and reads back (``diffguide import``, ``fit
--format auto``) to the same merged data to the printed precision:

- ``majda2012_measurements_wide.csv`` — the wide "targets × runs" layout (ISO 230-2 style,
  ``diffguide.io.importers``): one block per channel, ``;`` separated with decimal commas,
  targets in machine coordinates (x = target − 400 mm, stated by its ``x0_mm`` line: the
  stroke runs 50–750 mm), a
  temperature column (ignored with a note), levels in mm/m.
- ``majda2012_measurements_semicolon.csv`` — the long layout as a German-locale export: tab
  separated, decimal commas, directions ``positive``/``negative``, a ``temperature_C`` column,
  positions in machine coordinates (``--x0-mm 400``), and the levels as differential pairs: a
  ``reference`` column holding a reference level's reading (a slow tilt of the machine bed,
  made up), the ``value`` column the measuring level's (true value + reference).

Run ``python data/make_import_examples.py`` (instant).
"""

import csv
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))
X0_MM = 400.0


def _rows():
    with open(os.path.join(HERE, "majda2012_measurements.csv"), encoding="utf-8") as fh:
        return list(csv.DictReader(line for line in fh if not line.startswith("#")))


def _comma(x: float, digits: int) -> str:
    return f"{x:.{digits}f}".replace(".", ",")


def _reference(position_mm: float, run: str) -> float:
    """The made-up reference level reading (µm/m): a slow bed tilt, different per run."""
    return 3.0 * math.sin(position_mm / 170.0 + int(run)) + 0.5 * int(run)


def wide(rows) -> str:
    out = [
        "# diffguide wide measurement layout (targets x runs), made from "
        "majda2012_measurements.csv",
        "# targets in machine coordinates: x = target - 400 mm",
        "x0_mm;400,0",
    ]
    channels = {}
    for r in rows:
        channels.setdefault((r["point"], r["quantity"], r["instrument"]), []).append(r)
    for (point, quantity, instrument), rs in channels.items():
        level = instrument == "level"
        runs = sorted({r["run"] for r in rs}, key=int)
        cols = [f"run{k}_{d}" for k in runs for d in ("fwd", "bwd")]
        out += [
            f"point;{point}",
            f"x_mm;{_comma(float(rs[0]['x_mm']), 1)}",
            f"y_mm;{_comma(float(rs[0]['y_mm']), 1)}",
            f"quantity;{quantity}",
            f"unit;{'mm/m' if level else 'µm/m'}",
            f"instrument;{instrument}",
            "target_mm;" + ";".join(cols) + ";temperature_C",
        ]
        table = {}
        for r in rs:
            d = "fwd" if r["direction"] == "forward" else "bwd"
            v = float(r["value"])
            table.setdefault(float(r["position_mm"]), {})[f"run{r['run']}_{d}"] = (
                _comma(v * 1e-3, 6) if level else _comma(v, 3)
            )
        for k, (x, vals) in enumerate(sorted(table.items())):
            out.append(
                ";".join(
                    [_comma(x + X0_MM, 1)]
                    + [vals.get(c, "") for c in cols]
                    + [_comma(20.0 + 0.01 * k, 2)]
                )
            )
        out.append("")
    return "\n".join(out)


def semicolon(rows) -> str:
    head = [
        "position_mm",
        "point",
        "x_mm",
        "y_mm",
        "quantity",
        "value",
        "reference",
        "unit",
        "run",
        "direction",
        "instrument",
        "temperature_C",
    ]
    out = [
        "# long layout, German-locale export: tab separated, decimal commas; positions in "
        "machine coordinates (x0 = 400 mm); levels as differential pairs",
        "\t".join(head),
    ]
    for k, r in enumerate(rows):
        pos = float(r["position_mm"])
        v = float(r["value"])
        ref = ""
        if r["instrument"] == "level":
            refv = round(_reference(pos, r["run"]), 3)
            ref, v = _comma(refv, 3), v + refv
        out.append(
            "\t".join(
                [
                    _comma(pos + X0_MM, 1),
                    r["point"],
                    _comma(float(r["x_mm"]), 1),
                    _comma(float(r["y_mm"]), 1),
                    r["quantity"],
                    _comma(v, 3),
                    ref,
                    "µm/m",
                    r["run"],
                    "positive" if r["direction"] == "forward" else "negative",
                    r["instrument"],
                    _comma(20.0 + 0.001 * (k % 100), 3),
                ]
            )
        )
    return "\n".join(out) + "\n"


def main():
    rows = _rows()
    for name, text in (
        ("majda2012_measurements_wide.csv", wide(rows)),
        ("majda2012_measurements_semicolon.csv", semicolon(rows)),
    ):
        with open(os.path.join(HERE, name), "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
        print(f"wrote data/{name}")


if __name__ == "__main__":
    main()
