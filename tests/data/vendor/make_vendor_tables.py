r"""Seven measurement files laid out as instrument software writes them, each with the canonical
long file that carries the same readings (issue 27's acceptance: each loads through a profile
written from the README's profile documentation alone, ``tests/data/vendor/*.toml``).

The readings come from ``data/majda2012_measurements.csv`` (every third position, runs 1-2 or
1-5), written in the vendor's units, encodings and separators:

1. ``laser.csv`` — a laser system's CSV: UTF-8 with a byte-order mark, CRLF line ends, a key/value
   header block, targets in machine coordinates (x0 = 400 mm), one column per run and
   direction ("Run 1 Fwd", "Run 1 Rev"); P5 pitch (EBX) in µm/m.
2. ``laser_ascii.txt`` — a laser ASCII export: ``key : value`` lines, a ``Targets:`` block (the
   positions, several per line), a ``Data:`` block of ``run direction target-index value``
   records, whitespace separated; P5 yaw (ECX) in arcsec.
3. ``levels_latin1.csv`` — a level pair's export: Latin-1, ``;``, decimal comma, German column
   names, ``hin``/``rück``, measuring and reference level columns; P1 EBX and EAX, the EAX
   level mounted reversed (its readings negated: the profile's sign).
4. ``inch_tab.txt`` — a tab-separated export in inches and arc-seconds with ``Up``/``Down``
   runs; P2 EBX.
5. ``iso230_summary.csv`` — an ISO 230-2 summary table in cp1252: per target the mean per
   direction of 5 runs, s and R per direction, B; P3 EBX (µm/m), ``;`` and decimal comma.
6. ``grid.exx`` — an ISG/Etalon vendor exchange grid: ``//`` comments, ``[EBX]``/``[ECX]``
   sections with ``Gridpoints = { ... }`` in mm and rad (run 1 forward at P5), and sections
   of another axis and a constant to skip.
7. ``sixdof.csv`` — a 6-DOF laser's one-row-per-target file at P4: all six errors per row
   (EAX and EBX from the data set, the others made up), µm and µrad, yaw mounted reversed.

``python tests/data/vendor/make_vendor_tables.py`` rewrites them next to this script (instant);
``tests/test_profiles.py`` writes them to a temporary folder with :func:`write_all`.
"""

import csv
import math
import os
from pathlib import Path

HERE = Path(__file__).resolve().parent
DATA = HERE.parents[2] / "data" / "majda2012_measurements.csv"
X0_MM = 400.0
ARCSEC = math.pi / (180 * 3600)
CANONICAL_HEADER = ("position_mm,point,x_mm,y_mm,quantity,value,unit,sigma,run,direction,"
                    "instrument")


def _rows():
    with open(DATA, encoding="utf-8") as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    keep = sorted({float(r["position_mm"]) for r in rows})[::3]
    return [r for r in rows if float(r["position_mm"]) in keep]


def _select(rows, point, quantity, runs=("1", "2")):
    return [r for r in rows if r["point"] == point and r["quantity"] == quantity
            and r["run"] in runs]


def _canonical(rows) -> str:
    """The canonical long file of ``rows`` (dicts with the canonical columns)."""
    out = [CANONICAL_HEADER]
    for r in rows:
        out.append(",".join(str(r.get(c, "")) for c in CANONICAL_HEADER.split(",")))
    return "\n".join(out) + "\n"


def _by_target(rows):
    table = {}
    for r in rows:
        d = "Fwd" if r["direction"] == "forward" else "Rev"
        table.setdefault(float(r["position_mm"]), {})[f"Run {r['run']} {d}"] = r["value"]
    return table


def laser_csv(rows):
    sel = _select(rows, "P5", "EBX")
    cols = [f"Run {k} {d}" for k in ("1", "2") for d in ("Fwd", "Rev")]
    lines = ["Laser Calibration Export,", "Operator,A. Metrologist", "Date,2026-11-26 10:04:31",
             "Machine,MC-1000 table X", "Measurement,Pitch", "Point,P5", "X position (mm),0",
             "Y position (mm),0", "Units,µm/m", "Air temperature,20.1 °C", "",
             "Target (mm)," + ",".join(cols) + ",Material temp (°C)"]
    for k, (x, vals) in enumerate(sorted(_by_target(sel).items())):
        lines.append(f"{x + X0_MM:.1f}," + ",".join(vals[c] for c in cols) + f",{20 + k / 100:.2f}")
    data = ("\r\n".join(lines) + "\r\n").encode("utf-8-sig")
    return data, _canonical(sel)


def laser_ascii(rows):
    sel = _select(rows, "P5", "ECX")
    targets = sorted({float(r["position_mm"]) for r in sel})
    lines = ["LASER SYSTEM ASCII EXPORT  v4.2", "Axis : X", "Test : Angular yaw",
             "Units : arcsec", "Point : P5", "Location X : 0.0", "Location Y : 0.0", "Targets:"]
    for k in range(0, len(targets), 6):
        lines.append("  ".join(f"{t + X0_MM:.3f}" for t in targets[k:k + 6]))
    lines.append("Data:")
    canon = []
    for r in sel:
        arcsec = float(r["value"]) * 1e-6 / ARCSEC
        text = f"{arcsec:.9f}"
        lines.append(f"{r['run']}  {'F' if r['direction'] == 'forward' else 'R'}  "
                     f"{targets.index(float(r['position_mm'])) + 1}  {text}")
        canon.append({**r, "value": text, "unit": "arcsec"})
    return ("\n".join(lines) + "\n").encode("ascii"), _canonical(canon)


def _reference(x, run):
    """A made-up reference level reading (µm/m), 3 decimals."""
    return round(2.0 * math.sin(x / 130.0 + int(run)) + 0.4 * int(run), 3)


def levels_latin1(rows):
    sel = _select(rows, "P1", "EBX") + _select(rows, "P1", "EAX")
    lines = ["Neigungsmessung Führungsbahn - Differenzmessung",
             "Messpunkt;X (mm);Y (mm);Größe;Lauf;Richtung;Position (mm);Messwert (µm/m);"
             "Referenz (µm/m);Temperatur (°C)"]
    names = {"EBX": "Neigung längs", "EAX": "Neigung quer"}
    for r in sel:
        sign = -1 if r["quantity"] == "EAX" else 1  # the EAX level is mounted reversed
        ref = _reference(float(r["position_mm"]), r["run"])
        meas = round(sign * float(r["value"]) + ref, 3)
        lines.append(";".join([
            "P1", "450,0", "200,0", names[r["quantity"]], r["run"],
            "hin" if r["direction"] == "forward" else "rück",
            f"{float(r['position_mm']) + X0_MM:.1f}".replace(".", ","),
            f"{meas:.3f}".replace(".", ","), f"{ref:.3f}".replace(".", ","), "20,3"]))
    # the reversed level reads −value: its measuring column is −value + ref, its reference
    # column ref; the profile's sign −1 on both makes measuring − reference = value
    canon = [dict(r) for r in sel]
    return ("\n".join(lines) + "\n").encode("latin-1"), _canonical(canon)


def inch_tab(rows):
    sel = _select(rows, "P2", "EBX")
    lines = ["Axis\tX", "Point\tP2", "X (mm)\t-450", "Y (mm)\t200", "",
             "Target (in)\tRun\tDirection\tPitch (arc-sec)"]
    canon = []
    for r in sel:
        x_in = (float(r["position_mm"]) + X0_MM) / 25.4
        arcsec = f"{float(r['value']) * 1e-6 / ARCSEC:.9f}"
        lines.append(f"{x_in:.9f}\tRun {r['run']}\t"
                     f"{'Up' if r['direction'] == 'forward' else 'Down'}\t{arcsec}")
        canon.append({**r, "value": arcsec, "unit": "arcsec"})
    return ("\n".join(lines) + "\n").encode("ascii"), _canonical(canon)


def iso_summary(rows, x0=X0_MM, builtin=False):
    sel = _select(rows, "P3", "EBX", runs=("1", "2", "3", "4", "5"))
    xy = ("x_mm;-450", "y_mm;-200") if builtin else ("X (mm);-450", "Y (mm);-200")
    lines = ["Positioniergenauigkeit – ISO 230-2 Auswertung", "Point;P3", *xy,
             "Quantity;EBX", "Unit;µm/m", "Instrument;level", "Runs;5", "",
             "Target (mm);Mean fwd;Mean bwd;s fwd;s bwd;R fwd;R bwd;B"]
    canon = []
    by = {}
    for r in sel:
        by.setdefault(float(r["position_mm"]), {}).setdefault(r["direction"], []).append(
            float(r["value"]))
    for x, dirs in sorted(by.items()):
        cells = [f"{x + x0:.1f}"]
        stats = {}
        for d in ("forward", "backward"):
            v = dirs[d]
            mean = sum(v) / len(v)
            s = math.sqrt(sum((a - mean) ** 2 for a in v) / (len(v) - 1))
            stats[d] = (f"{mean:.4f}", f"{s:.4f}")
            canon.append({"position_mm": x, "point": "P3", "x_mm": -450, "y_mm": -200,
                          "quantity": "EBX", "value": f"{mean:.4f}", "unit": "um/m",
                          "sigma": repr(float(f"{s:.4f}") / math.sqrt(len(v))), "run": "1",
                          "direction": d, "instrument": "level"})
        cells += [stats["forward"][0], stats["backward"][0], stats["forward"][1],
                  stats["backward"][1], "4,0000", "4,0000", "0,5000"]
        lines.append(";".join(c.replace(".", ",") for c in cells))
    return ("\r\n".join(lines) + "\r\n").encode("cp1252"), _canonical(canon)


def grid_exx(rows, x0=X0_MM):
    lines = ["// Etalon vendor exchange file, X axis, LaserTRACER", "// units: mm, rad",
             "[C0B]", "VALUE = 0.000022355737"]
    canon = []
    for q in ("EBX", "ECX"):
        sel = [r for r in _select(rows, "P5", q, runs=("1",)) if r["direction"] == "forward"]
        lines += [f"[{q}]", "Gridpoints = {"]
        for r in sel:
            rad = f"{float(r['value']) * 1e-6:.12f}"
            lines.append(f"          {float(r['position_mm']) + x0:.1f} {rad}")
            canon.append({**r, "value": rad, "unit": "rad"})
        lines.append(f"}}  // end of {q}")
    lines += ["[EXY]", "Gridpoints = {", "   0.0 0.0", "   700.0 0.000001", "}"]
    return ("\n".join(lines) + "\n").encode("ascii"), _canonical(canon)


def sixdof(rows, builtin=False):
    targets = sorted({float(r["position_mm"]) for r in rows})
    measured = {(float(r["position_mm"]), r["run"], r["direction"], r["quantity"]): r["value"]
                for r in rows if r["point"] == "P4" and r["run"] in ("1", "2")}
    xy = ("x_mm: 450", "y_mm: -200") if builtin else ("X (mm): 450", "Y (mm): -200")
    lines = ["6-DOF measurement", "Point: P4", *xy, "",
             "Target (mm),Run,Direction,Linear (µm),Horizontal straightness (µm),"
             "Vertical straightness (µm),Roll (µrad),Pitch (µrad),Yaw (µrad)"]
    canon = []
    for run in ("1", "2"):
        for d in ("forward", "backward"):
            for x in targets:
                made_up = {"EXX": f"{1.5 * math.sin(x / 200 + int(run)):.3f}",
                           "EYX": f"{0.8 * math.cos(x / 150):.3f}",
                           "EZX": f"{0.6 * math.sin(x / 90):.3f}",
                           "ECX": f"{2.0 * math.sin(x / 300) + 0.1 * int(run):.3f}"}
                vals = {q: measured.get((x, run, d, q)) or made_up[q]
                        for q in ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX")}
                for q, v in vals.items():
                    canon.append({"position_mm": x, "point": "P4", "x_mm": 450, "y_mm": -200,
                                  "quantity": q, "value": v,
                                  "unit": "um" if q in ("EXX", "EYX", "EZX") else "urad",
                                  "run": run, "direction": d, "instrument": "interferometer"})
                yaw = vals["ECX"][1:] if vals["ECX"].startswith("-") else "-" + vals["ECX"]
                yaw = vals["ECX"] if builtin else yaw  # the built-in profile has no sign
                lines.append(",".join([f"{x:.1f}", run, d] + [vals[q] for q in (
                    "EXX", "EYX", "EZX", "EAX", "EBX")] + [yaw]))
    return ("\n".join(lines) + "\n").encode("utf-8"), _canonical(canon)


#: file name -> (maker, profile file written from the README's documentation)
TABLES = {
    "laser.csv": (laser_csv, "laser.toml"),
    "laser_ascii.txt": (laser_ascii, "laser_ascii.toml"),
    "levels_latin1.csv": (levels_latin1, "levels_latin1.toml"),
    "inch_tab.txt": (inch_tab, "inch_tab.toml"),
    "iso230_summary.csv": (iso_summary, "iso230_summary.toml"),
    "grid.exx": (grid_exx, "grid_exx.toml"),
    "sixdof.csv": (sixdof, "sixdof.toml"),
}


def write_all(folder) -> dict:
    """Write every table and its canonical twin (``NAME.canonical.csv``) to ``folder``:
    ``{name: (table path, canonical path, profile path)}``."""
    folder = Path(folder)
    rows = _rows()
    out = {}
    for name, (make, profile) in TABLES.items():
        data, canon = make(rows)
        (folder / name).write_bytes(data)
        (folder / f"{name}.canonical.csv").write_text(canon, encoding="utf-8")
        out[name] = (folder / name, folder / f"{name}.canonical.csv", HERE / profile)
    return out


#: the examples of the built-in profiles (data/examples/): file name -> maker
EXAMPLES = {
    "exx_grid.exx": lambda rows: grid_exx(rows, x0=0.0),
    "iso230-2-summary.csv": lambda rows: iso_summary(rows, x0=0.0, builtin=True),
    "6dof.csv": lambda rows: sixdof(rows, builtin=True),
}


def write_examples(folder) -> None:
    """The built-in profiles' example files and their canonical twins, in ``folder``."""
    rows = _rows()
    for name, make in EXAMPLES.items():
        data, canon = make(rows)
        (Path(folder) / name).write_bytes(data)
        (Path(folder) / f"{name}.canonical.csv").write_text(canon, encoding="utf-8")
        print(f"wrote {os.path.join(folder, name)}")


if __name__ == "__main__":
    for name in write_all(HERE):
        print(f"wrote {os.path.join(HERE, name)}")
    write_examples(HERE.parents[2] / "data" / "examples")
