"""Write docs/file-formats.md's list of machine-file keys (between its CONFIG-KEYS markers) from
the one table that also drives validation, ``diffguide config`` and ``--explain``
(:data:`diffguide.io.config_spec.KEYS` with its defaults, ``RIB_SCHEMA``, ``FIT_SCHEMA``, and
the ``[export]`` settings of :mod:`diffguide.studies.exports.settings`).

    python docs/config_keys.py            # rewrite the block
    python docs/config_keys.py --check    # exit 1 if the page differs from what it would write
"""

import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "file-formats.md"
BEGIN, END = "<!-- CONFIG-KEYS -->", "<!-- /CONFIG-KEYS -->"


def _value(v) -> str:
    if v is None:
        return "the machine's"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, dict):
        return ",".join(f"{k}={x}" for k, x in v.items())
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def _allowed(kind: str, lo, hi) -> str:
    if kind.startswith("str:"):
        return " or ".join(f"`{w}`" for w in kind[4:].split("|"))
    if kind == "bool":
        return "true or false"
    each = {"pair": "two numbers, each ", "list": "numbers, each ",
            "prior": "[value, lo, hi], "}.get(kind, "")
    return f"{each}{'an integer ' if kind == 'int' else ''}in [{lo:g}, {hi:g}]"


def _md(text: str) -> str:
    """Prose for a table cell: Markdown's emphasis and link characters escaped."""
    return "".join("\\" + ch if ch in "*_[]|" else ch for ch in str(text))


def _rows(table: dict) -> list[str]:
    out = ["| key | default | allowed | meaning |", "|---|---|---|---|"]
    for key, (default, kind, lo, hi, help_) in table.items():
        out.append(f"| `{key}` | `{_value(default)}` | {_md(_allowed(kind, lo, hi))} | {_md(help_)} |")
    return out


def block() -> str:
    """The generated block, markers included."""
    from diffguide.io.config_spec import FIT_SCHEMA, RIB_SCHEMA, schema
    from diffguide.studies.exports.settings import SETTINGS

    lines = [BEGIN, "<!-- written by docs/config_keys.py from diffguide.io.config_spec; "
             "do not edit -->", ""]
    for section, table in schema().items():
        lines += [f"`[{section}]`", "", *_rows(table), ""]
    lines += ["`[[ribs]]` (one table per rib; default: none)", "", *_rows(RIB_SCHEMA), ""]
    lines += ["`[fit]` (how `diffguide fit` treats what is not known of the machine)", "",
              *_rows(FIT_SCHEMA), ""]
    lines += ["`[export]` (the compensation exports' controller settings)", "",
              "| key | option | default | allowed |", "|---|---|---|---|"]
    for key, (option, default, allowed) in SETTINGS.items():
        lines.append(f"| `{key}` | `{option}` | `{_value(default) if default is not None else 'none'}`"
                     f" | {_md(allowed)} |")
    lines += ["", END]
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--check", action="store_true", help="compare, write nothing")
    a = p.parse_args(argv)
    text = PAGE.read_text(encoding="utf-8")
    pattern = re.compile(re.escape(BEGIN) + ".*?" + re.escape(END), re.S)
    if not pattern.search(text):
        sys.exit(f"{PAGE}: no {BEGIN} ... {END} markers")
    new = pattern.sub(lambda _: block(), text)
    if a.check:
        if new != text:
            print(f"{PAGE.relative_to(ROOT)} is stale: python docs/config_keys.py", file=sys.stderr)
            return 1
        return 0
    PAGE.write_text(new, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
