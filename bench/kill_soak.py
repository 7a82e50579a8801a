"""Random SIGKILLs and Ctrl-Cs during ``diffguide fit``: is the output folder always complete?

Runs the bundled fit once to completion (the previous result, and the run's duration ``T``),
then ``--kills`` runs killed (SIGKILL) and ``--interrupts`` runs interrupted (SIGINT, as Ctrl-C
sends it), in random order, at uniformly random times in ``[start, T]`` (``T`` lowered when a
run ends first), each into the same ``--out``; after each, the output folder must hold a
complete result (``report.json`` parses, ``rails.csv`` present), the previous one or the new one.
Every interrupted run must exit 130 without a traceback on stderr. A last run to completion must leave no hidden
``.<out>.*`` leftovers beside the folder. Prints the tally; exit status 1 when any check
failed. Run (on a quiet machine, or ``nice``'d):

    python bench/kill_soak.py [--kills 100] [--interrupts 100] [--mesh 6x3]
"""

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "majda2012_measurements.csv"
#: A run that exits 0 this soon (s) after its SIGINT was past its last checkpoint already.
EXIT_RACE_S = 0.5


def fit_command(out: Path, mesh: str = "6x3", max_steps: int = 3) -> list[str]:
    """The bundled fit on a coarse mesh (the ``diffguide`` of this interpreter)."""
    return [sys.executable, "-m", "diffguide.cli", "fit", "--preset", "majda2012",
            "--measurements", str(DATA), "--mesh", mesh, "--max-steps", str(max_steps),
            "--out", str(out), "-q"]


def _env() -> dict:
    import diffguide

    src = str(Path(diffguide.__file__).resolve().parents[1])
    path = os.environ.get("PYTHONPATH", "")
    return {**os.environ, "PYTHONPATH": src + (os.pathsep + path if path else "")}


def complete(out: Path) -> str | None:
    """``None`` where ``out`` holds a complete fit result, else what is wrong."""
    try:
        report = json.loads((out / "report.json").read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        return f"report.json unreadable: {exc}"
    if not isinstance(report, dict):
        return "report.json is not an object"
    if not (out / "rails.csv").is_file():
        return "rails.csv missing"
    return None


def leftovers(out: Path) -> list[str]:
    """The hidden entries beside ``out`` that a run of it may create."""
    return sorted(p.name for p in out.parent.glob(f".{out.name}.*"))


def soak(out: Path, kills: int, interrupts: int, mesh: str = "6x3", start_s: float = 1.5,
         seed: int = 0, log=print) -> dict:
    """The loop of the module docstring; returns the tally (``failures`` lists each failed
    check)."""
    rng = random.Random(seed)
    env = _env()
    cmd = fit_command(out, mesh)
    tally = {"runs": 0, "killed": 0, "interrupted": 0, "exit_130": 0, "finished_first": 0,
             "new_result_kept": 0, "failures": []}

    def run_to_end(what: str) -> float:
        t = time.perf_counter()
        proc = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                              text=True)
        tally["runs"] += 1
        if proc.returncode != 0:
            tally["failures"].append(f"{what}: exit {proc.returncode}: {proc.stderr[-500:]}")
        return time.perf_counter() - t

    duration = run_to_end("first run")
    log(f"first run: {duration:.1f} s")
    signals = [signal.SIGKILL] * kills + [signal.SIGINT] * interrupts
    rng.shuffle(signals)
    for i, sig in enumerate(signals):
        before = (out / "report.json").stat().st_mtime_ns if complete(out) is None else None
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                text=True)
        tally["runs"] += 1
        time.sleep(rng.uniform(start_s, max(start_s, duration)))
        if proc.poll() is not None:  # finished before the signal: not a test of it
            tally["finished_first"] += 1
            proc.communicate()
            duration = min(duration, 0.95 * (time.perf_counter() - t0))  # warm caches: faster
        else:
            t_sig = time.perf_counter()
            proc.send_signal(sig)
            _, err = proc.communicate()
            after = time.perf_counter() - t_sig
            name = signal.Signals(sig).name
            if sig == signal.SIGKILL:
                tally["killed"] += 1
            elif (proc.returncode == 0 and after < EXIT_RACE_S and "interrupted" not in err
                  and complete(out) is None):
                # the run had passed its last checkpoint when the signal came and ended within
                # EXIT_RACE_S with its result committed: a race with the process's exit (a
                # Ctrl-C after the work is done cannot undo it), not a lost interrupt — one of
                # those lets the run go on for seconds (and the swallowed Ctrl-C tests of
                # tests/test_crash_outputs.py catch it at the checkpoints)
                tally["finished_first"] += 1
            else:
                tally["interrupted"] += 1
                if "Traceback" in err or "Exception ignored" in err:  # one line, no traceback
                    tally["failures"].append(f"run {i}: SIGINT printed a traceback: {err[-800:]}")
                if proc.returncode == 130:
                    tally["exit_130"] += 1
                else:
                    tally["failures"].append(f"run {i}: SIGINT gave exit {proc.returncode}: "
                                             f"{err[-500:]}")
            wrong = complete(out)
            if wrong:
                tally["failures"].append(f"run {i} ({name}): {out} incomplete: {wrong}")
            elif before is not None and (out / "report.json").stat().st_mtime_ns != before:
                tally["new_result_kept"] += 1
    run_to_end("last run")
    left = leftovers(out)
    if left:
        tally["failures"].append(f"leftovers after the last run: {left}")
    if complete(out):
        tally["failures"].append(f"last run: {complete(out)}")
    return tally


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kills", type=int, default=100)
    ap.add_argument("--interrupts", type=int, default=100)
    ap.add_argument("--mesh", default="6x3")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None, help="output folder (default: a temporary one)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(a.out) if a.out else Path(tmp) / "out"
        tally = soak(out, a.kills, a.interrupts, a.mesh, seed=a.seed)
    for k, v in tally.items():
        if k != "failures":
            print(f"{k}: {v}")
    print(f"failures: {len(tally['failures'])}")
    for f in tally["failures"]:
        print(f"  {f}")
    return 1 if tally["failures"] else 0


if __name__ == "__main__":
    sys.exit(main())
