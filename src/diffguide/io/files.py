"""Deprecated: ``diffguide.io.files`` was split into :mod:`diffguide.io.atomic` (atomic writes)
and :mod:`diffguide.io.rails_csv` (the rails CSV reader); this name works for one release."""

import warnings

from .atomic import atomic_savefig as atomic_savefig
from .atomic import atomic_write as atomic_write
from .atomic import atomic_write_text as atomic_write_text
from .rails_csv import read_rails_csv as read_rails_csv

warnings.warn(
    "diffguide.io.files is split into diffguide.io.atomic and diffguide.io.rails_csv",
    DeprecationWarning,
    stacklevel=2,
)
