"""Every notebook's source is a jupytext percent script, ``notebooks/NN_name.py`` (``# %%``
cells, ``# %% [markdown]`` cells); the suite builds the notebook from it with jupytext and runs
it top to bottom with nbclient, so none can rot. The committed ``NN_name.ipynb`` beside it (its
outputs, for reading without running) holds the same cells: after editing a script,
``jupytext --sync notebooks/NN_name.py`` updates them (outputs kept), and
``jupytext --to ipynb --execute notebooks/NN_name.py`` refreshes the outputs too."""

from pathlib import Path

import jupytext
import nbformat
import pytest
from nbclient import NotebookClient

HERE = Path(__file__).parent.parent / "notebooks"
SCRIPTS = sorted(HERE.glob("[0-9][0-9]_*.py"))


def _cells(nb) -> list[tuple[str, str]]:
    return [(c.cell_type, c.source) for c in nb.cells]


def test_each_notebook_is_a_percent_script_with_its_committed_notebook():
    """The scripts are jupytext's percent format, paired with the committed ``.ipynb`` (one for
    each script, none without one), whose cells are those jupytext reads from the script."""
    assert SCRIPTS, "no notebook scripts"
    assert sorted(HERE.glob("*.ipynb")) == [p.with_suffix(".ipynb") for p in SCRIPTS]
    for script in SCRIPTS:
        built = jupytext.read(script)
        meta = built.metadata["jupytext"]
        assert meta["text_representation"]["format_name"] == "percent", script.name
        assert meta["formats"] == "ipynb,py:percent", script.name
        committed = nbformat.read(script.with_suffix(".ipynb"), as_version=4)
        assert _cells(committed) == _cells(built), (
            f"{script.with_suffix('.ipynb').name} differs from {script.name}: "
            f"jupytext --sync notebooks/{script.name}")
        assert committed.metadata["kernelspec"] == built.metadata["kernelspec"]


@pytest.mark.parametrize("path", SCRIPTS, ids=[p.stem for p in SCRIPTS])
def test_notebook_runs(path):
    nb = jupytext.read(path)  # the percent script -> a notebook (no outputs)
    client = NotebookClient(
        nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(HERE)}}
    )
    client.execute()  # raises CellExecutionError naming the cell on any error
    errors = [
        o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"
    ]
    assert not errors
