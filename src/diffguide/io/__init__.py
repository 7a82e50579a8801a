"""The edge: files and formats. Atomic writes, the rails CSV, machine configuration files (TOML).
The core never imports this package."""

from .config import default_config as default_config
from .config import dump_config as dump_config
from .config import load_config as load_config
from .files import atomic_savefig as atomic_savefig
from .files import atomic_write as atomic_write
from .files import atomic_write_text as atomic_write_text
from .files import read_rails_csv as read_rails_csv
