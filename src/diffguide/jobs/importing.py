"""The import job: measurement files in any supported layout, or read through a profile, ->
one canonical long CSV, every output of ``diffguide import`` (:func:`import_job`); with
``draft_profile``, a draft profile of one file instead.

:class:`ImportSettings` holds every option; :func:`import_job` reads and merges the files (the
checks ``diffguide fit`` makes) and returns an :class:`ImportResult` holding the readings, the
merged data set, what was read and how (:meth:`ImportResult.explain_lines`), the notes and the
canonical CSV's text; :meth:`ImportResult.write` writes it atomically. Nothing heavy is
imported until the job runs.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path


@dataclasses.dataclass(frozen=True)
class ImportSettings:
    """Every option of ``diffguide import``, with the command line's defaults: the ``input``
    files, their ``layout`` (auto, long, wide) or ``profile`` (with ``profile_set`` items),
    ``encoding``, ``x0_mm`` (mm, or ``"middle"``), the merge's allowances; ``out`` the
    canonical CSV (optional with ``explain``); ``draft_profile`` a TOML path: draft the one
    file's profile instead (``overwrite_draft``; ``preset``/``config``: list the machine's
    control points in it). Checked at construction (``ValueError`` naming the option)."""

    input: tuple[str, ...]
    layout: str = "auto"
    profile: tuple[str, ...] | None = None
    profile_set: tuple[str, ...] | None = None
    accept_file_conflicts: bool = False
    encoding: str | None = None
    x0_mm: float | str | None = None
    allow_many_positions: bool = False
    explain: bool = False
    out: str | None = None
    draft_profile: str | None = None
    overwrite_draft: bool = False
    preset: str | None = None
    config: str | None = None

    def __post_init__(self):
        files = self.input
        object.__setattr__(self, "input", (str(files),) if isinstance(files, (str, Path))
                           else tuple(map(str, files)))
        for name in ("out", "draft_profile", "config"):
            v = getattr(self, name)
            object.__setattr__(self, name, None if v is None else str(v))
        for name in ("profile", "profile_set"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, tuple(getattr(self, name)))
        if not self.input:
            raise ValueError("diffguide import: at least one FILE is needed")
        if self.layout not in ("auto", "long", "wide"):
            raise ValueError(f"--format must be auto, long or wide, got {self.layout!r}")
        if self.draft_profile is not None:
            if len(self.input) != 1 or self.profile or self.out:
                raise ValueError("--draft-profile drafts one FILE's profile (without --profile "
                                 "and --out); then read it: --profile OUT.toml")
        elif self.out is None and not self.explain:
            raise ValueError("diffguide import: --out FILE.csv is required (or --explain)")

    @classmethod
    def fields(cls) -> tuple[str, ...]:
        """The settings' names (the options' destinations)."""
        return tuple(f.name for f in dataclasses.fields(cls))


@dataclasses.dataclass
class ImportResult:
    """What :func:`import_job` read: the readings, the merged data set
    (:class:`~diffguide.inverse.data.Measurements`), per file what was read and how
    (``infos``), the notes, and the canonical CSV's text (``text``); for a draft, the
    profile's text (``draft``) and the keys left to complete (``todo``)."""

    settings: ImportSettings
    readings: list
    measurements: object
    infos: list
    notes: list
    text: str | None
    draft: str | None = None
    todo: list | None = None

    def explain_lines(self) -> list[str]:
        """``--explain``'s lines, one block per file."""
        return explain_lines(self.infos)

    def write(self, out: str | Path | None = None) -> list[str]:
        """Write the canonical CSV to ``out`` (default: the settings' ``out``) atomically, or
        the draft profile to ``draft_profile`` (refused over an existing file unless
        ``overwrite_draft``); returns the path written (none for an ``explain`` alone)."""
        s = self.settings
        if self.draft is not None:
            from ..io.profile_draft import write_draft

            path = s.draft_profile if out is None else str(out)
            write_draft(path, self.draft, s.overwrite_draft)
            return [path]
        out = s.out if out is None else out
        if out is None:
            return []
        from ..io.atomic import atomic_write_text

        atomic_write_text(out, self.text)
        return [str(out)]


def import_job(settings: ImportSettings) -> ImportResult:
    """Run ``diffguide import``'s work for ``settings``: read every file, merge them as the
    fit does (its refusals, here), and compute the canonical CSV; or draft the profile.
    ``ValueError`` for bad input."""
    from ..io.importers import format_long, import_many
    from ..io.measurements import merge_readings
    from .inputs import load_profile_args

    s = settings
    if s.draft_profile is not None:
        return _draft(s)
    notes: list[str] = []
    infos: list[dict] = []
    readings = import_many(list(s.input), s.layout, s.x0_mm, notes, infos,
                           profile=load_profile_args(s, s.input), encoding=s.encoding)
    for info in infos:
        mine = [r for r in readings if r.source == info["file"]]
        info["readings"] = len(mine)
        info["channels"] = sorted({f"{r.quantity} at {r.point} ({r.instrument})" for r in mine})
    source = ", ".join(s.input)
    meas = merge_readings(readings, source=source, notes=notes,  # validates what fit sees
                          allow_many_positions=s.allow_many_positions,
                          allow_conflicts=s.accept_file_conflicts)
    x0 = "; ".join(f"{i['file']}: x0 = {i['x0_mm']:g} mm" for i in infos)
    text = format_long(readings, comment=f"imported from {source} by diffguide import\n"
                                         f"positions are table positions x ({x0})")
    return ImportResult(s, readings, meas, infos, notes, text)


def _draft(s: ImportSettings) -> ImportResult:
    """The draft of the one file's profile, with the machine's control points where a preset
    or a machine file is named."""
    from ..io.profile_draft import draft_profile
    from .study import machine_config

    points = machine_config(s)["points"] if (s.config or s.preset) else None
    text, todo = draft_profile(s.input[0], s.encoding, points)
    return ImportResult(s, [], None, [], [], None, text, list(todo))


def explain_lines(infos) -> list[str]:
    """What was read and how, one block per file (``infos``: the importers' statements)."""
    out = []
    for info in infos:
        out.append(f"{info['file']}:")
        out.append(f"  layout: {info.get('layout')}; encoding: {info.get('encoding')}; "
                   f"separator: {info.get('separator')!r}; decimal mark: "
                   f"{info.get('decimal')!r}")
        if info.get("metadata"):
            out.append("  metadata: " + "; ".join(f"{k} = {v}" for k, v in
                                                  info["metadata"].items()))
        if info.get("header"):
            out.append(f"  header (line {info['header_line']}): {', '.join(info['header'])}")
        for block in info.get("blocks", []):
            out.append(f"  block {block}")
        if info.get("position_column"):
            out.append(f"  positions: column {info['position_column']!r}")
        for col, what in info.get("columns", {}).items():
            shown = ", ".join(what[:4]) + (f" (+{len(what) - 4} more)" if len(what) > 4 else "")
            out.append(f"  column {col!r} -> {shown}")
        if info.get("channels"):
            out.append(f"  channels: {', '.join(info['channels'])}")
        out.append(f"  x0 = {info['x0_mm']:g} mm ({info['x0_source']})")
        read = [f"{info['readings']} readings" if "readings" in info else "",
                f"{info['rows']} table rows" if "rows" in info else "",
                f"{info['missing_cells']} empty cells (missing readings)"
                if info.get("missing_cells") else "",
                f"lines skipped: {', '.join(map(str, info['lines_skipped'][:10]))}"
                if info.get("lines_skipped") else "",
                f"sections skipped: {', '.join(info['blocks_skipped'][:6])}"
                if info.get("blocks_skipped") else ""]
        out.append("  " + "; ".join(r for r in read if r))
    return out
