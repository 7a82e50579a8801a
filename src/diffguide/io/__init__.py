"""The edge: files and formats. Atomic writes, the rails CSV, machine configuration files (TOML).
The core never imports this package."""

from .atomic import atomic_savefig as atomic_savefig
from .atomic import atomic_write as atomic_write
from .atomic import atomic_write_text as atomic_write_text
from .config import config_from_spec as config_from_spec
from .cross_config import load_cross_config as load_cross_config
from .config import default_config as default_config
from .config import dump_config as dump_config
from .config import load_config as load_config
from .config import spec_from_config as spec_from_config
from .rails_csv import read_rails_csv as read_rails_csv
from .rails_csv import read_rails_samples as read_rails_samples
from .superelement import SuperelementFileError as SuperelementFileError
from .superelement import read_ccx_reactions as read_ccx_reactions
from .superelement import read_cload as read_cload
from .superelement import read_dmig as read_dmig
from .superelement import read_inp_nodes as read_inp_nodes
from .superelement import read_user_element_matrix as read_user_element_matrix
from .superelement import reduced_from_reactions as reduced_from_reactions
from .superelement_file import load_imported_table as load_imported_table
