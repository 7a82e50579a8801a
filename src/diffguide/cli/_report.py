"""``diffguide fit``'s console lines for a metrologist, in report.html's words
(:func:`diffguide.io.report_html.straightness_lines`)."""

from ._common import say


def say_straightness(args, report) -> None:
    """The console's straightness lines and verdict (report.html's words)."""
    from ..io.report_html import straightness_lines, verdict_line

    st = report["straightness"]
    say(args, f"straightness, {st['reference_line']}; median and "
              f"{st['coverage_probability'] * 100:g} % interval of the fit's posterior draws:")
    for line in straightness_lines(st):
        say(args, f"  {line}")
    say(args, verdict_line(st))
