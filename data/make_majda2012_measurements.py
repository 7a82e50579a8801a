r"""Make the bundled data set ``majda2012_measurements.csv`` (and ``majda2012_truth.csv``).

A synthetic measurement of the ``majda2012`` machine's X axis, as a metrologist would take it
(SPEC §3, Majda 2012 §6): electronic levels at the four corners P1–P4 reading pitch (EBX) and
roll (EAX), and an angular interferometer with its optics at the table centre P5 reading pitch
(EBX) and yaw (ECX); positions every 20 mm over the 700 mm stroke; five bidirectional runs;
Gaussian reading noise of 4 µm/m (levels) and 2 µm/m (interferometer), the repeatabilities of
SPEC §2.5, independent between readings; values relative to the middle of the stroke (x = 0). The
fit does not need that: each channel's zero is a nuisance parameter of the fit.

Truth (:func:`truth_rails`, not a spline on any knot grid): each rail, each plane, is a quadratic
of the form of the paper's eq. 4 plus two long-wave sines (bending and twist of a bolted rail),
amplitudes of a few µm — rail errors of a precision size-25 guideway::

    e(s) = a₂ (s/1 m)² + a₁ (s/1 m) + Σ A_k sin(2π s/λ_k + φ_k)

(:data:`TRUTH`, µm and m). The forward model uses a finer table mesh (40 × 20 shells) than the
fit's default (20 × 10), so the fit also meets model error, as it would on a real machine.

Run ``python data/make_majda2012_measurements.py`` (about 20 s); fixed seed.
"""

import csv
import io
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SEED = 20120401
STROKE_MM = 700.0
STEP_MM = 20.0
RUNS = 5
FINE_MESH = (40, 20)
#: Sensors: (point, x_mm, y_mm, instrument, quantities).
SENSORS = (
    ("P1", 450.0, 200.0, "level", ("EBX", "EAX")),
    ("P2", -450.0, 200.0, "level", ("EBX", "EAX")),
    ("P3", -450.0, -200.0, "level", ("EBX", "EAX")),
    ("P4", 450.0, -200.0, "level", ("EBX", "EAX")),
    ("P5", 0.0, 0.0, "interferometer", ("EBX", "ECX")),
)
NOISE = {"level": 4.0, "interferometer": 2.0}  # µm/m per reading
#: Truth per (rail, plane): (a2 µm, a1 µm, ((A µm, λ m, φ rad), ...)).
TRUTH = {
    (1, "vertical"): (6.0, 2.0, ((1.2, 0.85, 0.4), (0.5, 0.55, 2.1))),
    (1, "horizontal"): (-3.0, 1.0, ((1.0, 1.10, 1.3), (0.4, 0.62, 0.2))),
    (2, "vertical"): (4.0, -1.5, ((1.0, 0.95, 2.6), (0.5, 0.60, 1.0))),
    (2, "horizontal"): (-2.0, 0.5, ((0.8, 0.90, 2.9), (0.4, 0.70, 1.7))),
}


def truth_profile(s, rail: int, plane: str) -> np.ndarray:
    """Truth deviation (m) of rail ``rail`` (1 or 2) in ``plane`` at ``s`` (m)."""
    a2, a1, waves = TRUTH[(rail, plane)]
    s = np.asarray(s, float)
    e = a2 * s**2 + a1 * s + sum(A * np.sin(2 * np.pi * s / lam + ph) for A, lam, ph in waves)
    return e * 1e-6


def truth_rails():
    """The truth as a pair of rail profiles for :func:`diffguide.joint_errors`."""
    import jax.numpy as jnp

    from diffguide.guideway.rails import AbstractRailProfile

    class TruthRail(AbstractRailProfile):
        rail: int

        def __call__(self, s):
            s = jnp.asarray(s, dtype=float)
            out = []
            for plane in ("horizontal", "vertical"):
                a2, a1, waves = TRUTH[(self.rail, plane)]
                e = a2 * s**2 + a1 * s
                for A, lam, ph in waves:
                    e = e + A * jnp.sin(2 * jnp.pi * s / lam + ph)
                out.append(e * 1e-6)
            return out[0], out[1]

    return TruthRail(1), TruthRail(2)


def points() -> dict[str, tuple[float, float]]:
    """Sensor locations {name: (x, y)} (m)."""
    return {name: (x * 1e-3, y * 1e-3) for name, x, y, _, _ in SENSORS}


def positions_mm() -> np.ndarray:
    n = int(round(STROKE_MM / STEP_MM)) + 1
    return np.linspace(-STROKE_MM / 2, STROKE_MM / 2, n)


def simulate(machine=None) -> np.ndarray:
    """Noise-free joint errors ``(n_pos, n_points, 6)`` (SI) of the truth on the fine mesh."""
    from diffguide.machine.kinematics import joint_errors
    from diffguide.machine.majda2012 import majda2012_machine

    if machine is None:
        machine = majda2012_machine(nx=FINE_MESH[0], ny=FINE_MESH[1], points=points())
    je = joint_errors(machine, truth_rails(), positions_mm() * 1e-3)
    if not bool(np.all(np.asarray(je.converged))):
        raise RuntimeError("the forward model did not converge")
    return np.asarray(je.errors)


def measurement_rows(errors: np.ndarray, rng: np.random.Generator) -> list[dict]:
    """Readings of :data:`RUNS` bidirectional runs with independent noise (µm/m)."""
    names = ("EXX", "EYX", "EZX", "EAX", "EBX", "ECX")
    pos = positions_mm()
    rows = []
    for run in range(1, RUNS + 1):
        for direction in ("forward", "backward"):
            order = range(len(pos)) if direction == "forward" else range(len(pos) - 1, -1, -1)
            for p, (name, x, y, inst, quantities) in enumerate(SENSORS):
                for q in quantities:
                    true = errors[:, p, names.index(q)] * 1e6  # µm/m
                    noisy = true + rng.normal(0.0, NOISE[inst], size=len(pos))
                    for i in order:
                        rows.append({
                            "position_mm": f"{pos[i]:.1f}", "point": name, "x_mm": f"{x:.1f}",
                            "y_mm": f"{y:.1f}", "quantity": q,
                            "value": f"{noisy[i]:.3f}", "unit": "um/m", "run": run,
                            "direction": direction, "instrument": inst,
                        })
    return rows


def _csv(header: str, rows: list[dict], columns) -> str:
    out = io.StringIO()
    out.write(header)
    w = csv.DictWriter(out, fieldnames=columns, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return out.getvalue()


def main(out_dir: str = HERE) -> None:
    from diffguide import enable_x64

    enable_x64()
    errors = simulate()
    rows = measurement_rows(errors, np.random.default_rng(SEED))
    head = (
        "# diffguide synthetic measurement of the majda2012 X axis "
        "(data/make_majda2012_measurements.py)\n"
        f"# levels at P1-P4 (EBX, EAX; {NOISE['level']} um/m per reading), interferometer at P5 "
        f"(EBX, ECX; {NOISE['interferometer']} um/m), {RUNS} bidirectional runs, seed {SEED}\n"
        "# truth profiles: majda2012_truth.csv; forward model on a 40 x 20 table mesh\n"
    )
    cols = ("position_mm", "point", "x_mm", "y_mm", "quantity", "value", "unit", "run",
            "direction", "instrument")
    with open(os.path.join(out_dir, "majda2012_measurements.csv"), "w", newline="") as fh:
        fh.write(_csv(head, rows, cols))
    s_mm = np.arange(-540.0, 540.0 + 1e-9, 2.0)
    truth = []
    for rail in (1, 2):
        v = truth_profile(s_mm * 1e-3, rail, "vertical") * 1e6
        h = truth_profile(s_mm * 1e-3, rail, "horizontal") * 1e6
        truth += [{"rail": rail, "s_mm": f"{s:.1f}", "vertical_um": f"{a:.5f}",
                   "horizontal_um": f"{b:.5f}"} for s, a, b in zip(s_mm, v, h)]
    with open(os.path.join(out_dir, "majda2012_truth.csv"), "w", newline="") as fh:
        fh.write(_csv("# truth rail profiles of majda2012_measurements.csv (see "
                      "make_majda2012_measurements.py)\n", truth,
                      ("rail", "s_mm", "vertical_um", "horizontal_um")))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else HERE)
