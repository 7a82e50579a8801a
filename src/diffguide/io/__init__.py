"""The edge: files and formats. Atomic writes, the rails CSV, machine configuration files (TOML).
The core never imports this package."""

from .atomic import atomic_savefig as atomic_savefig
from .atomic import atomic_write as atomic_write
from .atomic import atomic_write_text as atomic_write_text
from .config import config_from_spec as config_from_spec
from .config import default_config as default_config
from .config import dump_config as dump_config
from .config import load_config as load_config
from .config import spec_from_config as spec_from_config
from .rails_csv import read_rails_csv as read_rails_csv
from .rails_csv import read_rails_samples as read_rails_samples
