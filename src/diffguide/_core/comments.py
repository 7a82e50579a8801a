"""Text from the input (file names, point and machine names) written inside a line comment of
an output file, made unable to end the comment (:class:`CommentSyntax`)."""

import unicodedata
from collections.abc import Iterable
from dataclasses import dataclass


@dataclass(frozen=True)
class CommentSyntax:
    """A format's line comment: ``prefix`` starts it, the end of the line ends it. Text from
    the input (file names, point and machine names) must not end it: :meth:`text` writes every
    control or line-breaking character (``\\n``, ``\\r``, U+2028 ...), every character in
    ``reserved`` and, where ``ascii_only``, every non-ASCII one as a visible escape
    (``\\x0a``, ``\\u2028``), so a comment stays one comment line whatever it quotes."""

    prefix: str
    reserved: str = ""
    ascii_only: bool = True

    def text(self, value) -> str:
        """``value`` as text safe inside one comment line."""
        out = []
        for ch in str(value):
            if (unicodedata.category(ch)[0] in "CZ" and ch != " ") or ch in self.reserved \
                    or (self.ascii_only and ord(ch) > 126):
                out.append(f"\\x{ord(ch):02x}" if ord(ch) < 256 else f"\\u{ord(ch):04x}")
            else:
                out.append(ch)
        return "".join(out)

    def lines(self, texts: Iterable[str]) -> list[str]:
        """Each text as one comment line (``prefix``, a space, the text made safe)."""
        return [f"{self.prefix} {self.text(t)}".rstrip() if self.prefix else self.text(t)
                for t in texts]
