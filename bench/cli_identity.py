"""Before/after check of a refactor: the command line's outputs on the bundled jobs (fit, plan,
simulate, predict: the README's quick-start commands) written by a git revision and by the
current source, compared file by file, byte for byte, with the timing fields and the date
stamps masked.

    python bench/cli_identity.py [REVISION]     # default e1a2673, the main before the jobs layer

The revision is checked out in a temporary ``git worktree``; each side runs in its own
working folder holding a copy of data/ (so the relative paths the outputs name agree), with
its own compilation cache (a program exported by one side is never read by the other), its
``src`` on PYTHONPATH. Prints a table (file, identical) and exits 1 on any difference, 2 when
a command fails. A few minutes on a laptop core.
"""

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_REVISION = "e1a2673"
#: the README's quick-start commands (README.md: "Quick start", "Predict", "Simulate", "Plan")
COMMANDS = (
    ["fit", "--preset", "majda2012", "--measurements", "data/majda2012_measurements.csv",
     "--out", "fit-result", "--truth", "data/majda2012_truth.csv", "--export-compensation",
     "comp_P1.txt", "--at", "P1"],
    ["predict", "--fit", "fit-result", "--point", "Q1:300,100", "--point", "Q2:-300,-100",
     "--z-mm", "150", "--out", "predicted.csv"],
    ["simulate", "--preset", "majda2012", "--variant", "2", "--positions=-350:350:71", "--out",
     "errors.csv", "--plot", "errors.png"],
    ["plan", "--preset", "majda2012", "--grid", "7x3", "--levels", "4", "--interferometers",
     "1", "--compare", "bundled", "--out", "plan"],
)
#: what differs between two runs of the same command: seconds taken, the minute it ran
VOLATILE = re.compile(rb'("[a-z_]*seconds": )[-+0-9.e]+|\d{4}-\d\d-\d\d[ T]\d\d:\d\d(:\d\d)?'
                      rb'(\.\d+)?( ?UTC|Z|[+-]\d\d:\d\d)?')


def run_side(src: Path, work: Path, cache: Path) -> list[str]:
    """Run every command with ``src`` on PYTHONPATH in ``work``; returns the failures."""
    shutil.copytree(ROOT / "data", work / "data")
    env = {**os.environ, "PYTHONPATH": str(src), "TF_CPP_MIN_LOG_LEVEL": "3",
           "DIFFGUIDE_CACHE_DIR": str(cache)}
    failed = []
    for argv in COMMANDS:
        p = subprocess.run([sys.executable, "-m", "diffguide", *argv, "-q"], cwd=work, env=env,
                           capture_output=True, text=True)
        if p.returncode != 0:
            failed.append(f"{' '.join(argv[:1])} (exit {p.returncode}): {p.stderr[-800:]}")
    return failed


def steady(data: bytes, work: Path) -> bytes:
    """``data`` with the side's own folder, the seconds and the date stamps masked."""
    data = data.replace(str(work.resolve()).encode(), b"<WORK>")
    return VOLATILE.sub(lambda m: (m.group(1) or b"") + b"T", data)


def outputs(work: Path) -> dict:
    return {str(p.relative_to(work)): p for p in sorted(work.rglob("*"))
            if p.is_file() and not p.relative_to(work).parts[0] == "data"}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("revision", nargs="?", default=DEFAULT_REVISION)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="cli-identity-") as tmp:
        tmp = Path(tmp)
        tree = tmp / "before-tree"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree),
                        args.revision], check=True, capture_output=True)
        try:
            sides = {"before": (tree / "src", tmp / "before"), "after": (ROOT / "src",
                                                                          tmp / "after")}
            for name, (src, work) in sides.items():
                work.mkdir()
                print(f"{name}: {src} ...", flush=True)
                failed = run_side(src, work, tmp / f"cache-{name}")
                if failed:
                    print(f"{name}: failed:\n  " + "\n  ".join(failed))
                    return 2
            before, after = (outputs(w) for _, w in sides.values())
            rows, bad = [], 0
            for name in sorted(set(before) | set(after)):
                if name not in before or name not in after:
                    same = f"no (only {'before' if name in before else 'after'})"
                else:
                    a = steady(before[name].read_bytes(), sides["before"][1])
                    b = steady(after[name].read_bytes(), sides["after"][1])
                    same = "yes" if a == b else "no"
                bad += same != "yes"
                rows.append((name, same))
            width = max(len(n) for n, _ in rows)
            print(f"{'file'.ljust(width)}  identical")
            for name, same in rows:
                print(f"{name.ljust(width)}  {same}")
            print(f"{len(rows) - bad} of {len(rows)} files identical (revision {args.revision} "
                  "vs the working tree)")
            return 1 if bad else 0
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)],
                           capture_output=True)


if __name__ == "__main__":
    sys.exit(main())
