"""The words vendor files use for what a profile maps (read by :mod:`.profile_draft`): the
joint errors' common names, direction words of other languages, words that tell the
instrument, and the metadata keys of a point, its coordinates, the quantity and the unit."""

import re

#: common names of the X axis' joint errors (ISO 230-1), matched as words, longest first
QUANTITY_WORDS = (
    ("horizontal straightness", "EYX"), ("vertical straightness", "EZX"),
    ("straightness horizontal", "EYX"), ("straightness vertical", "EZX"),
    ("straightness y", "EYX"), ("straightness z", "EZX"),
    ("positioning", "EXX"), ("linear", "EXX"), ("position error", "EXX"),
    ("roll", "EAX"), ("pitch", "EBX"), ("yaw", "ECX"),
)
#: direction words beyond the long format's own (forward, fwd, up, rev, down, ...)
DIRECTION_WORDS = {"hin": "forward", "vor": "forward", "vorwärts": "forward",
                   "rück": "backward", "zurück": "backward", "rückwärts": "backward",
                   "aller": "forward", "retour": "backward", "↑": "forward", "↓": "backward",
                   "avanti": "forward", "indietro": "backward", "ida": "forward",
                   "vuelta": "backward"}
#: words in a file that tell its instrument
INSTRUMENT_WORDS = {
    "level": ("level", "wyler", "libelle", "neigung", "clinometer", "inclinometer",
              "niveau", "bluelevel", "levelmatic"),
    "interferometer": ("laser", "interferomet", "xl-80", "xl80", "6-dof", "6dof", "xm-60",
                       "api", "renishaw", "lasertracer", "etalon"),
}
#: metadata keys (lower case, one space) -> the [reading] field they give
META_ROLES = {
    "point": r"(measuring |control |measurement )?point( name)?|messpunkt|punkt|location|station",
    "x_mm": r"(location |point |position )?x( position| pos| coordinate)?( ?[(\[]mm[)\]])?"
            r"|x_mm",
    "y_mm": r"(location |point |position )?y( position| pos| coordinate)?( ?[(\[]mm[)\]])?"
            r"|y_mm",
    "z_mm": r"(location |point |position )?z( position| pos| coordinate)?( ?[(\[]mm[)\]])?"
            r"|z_mm|height( ?[(\[]mm[)\]])?",
    "quantity": r"quantity|measurement( type)?|test|error( type)?|größe|grösse|messgröße"
                r"|parameter|mode",
    "unit": r"units?|einheit|value units?",
    "instrument": r"instrument|sensor|gerät",
    "runs": r"runs|number of runs|läufe|n runs",
    "x0_mm": r"x0(_mm)?|x0 ?[(\[]mm[)\]]",
    "position_unit": r"position units?|length units?|target units?",
}


def quantity_of(text: str) -> str | None:
    """The ISO 230-1 name a column name or word means (``"Pitch (arcsec)"`` → ``"EBX"``,
    ``"EZX [µm]"`` → ``"EZX"``); ``None`` when it names none."""
    low = " ".join(str(text).lower().split())
    m = re.search(r"\be([xyzabc])x\b", low)
    if m:
        return f"E{m.group(1).upper()}X"
    for word, q in QUANTITY_WORDS:
        if re.search(rf"\b{re.escape(word)}\b", low):
            return q
    return None
