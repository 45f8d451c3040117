"""examples/quickstart.ipynb: committed without outputs, and it runs (nbclient, in a
Jupyter kernel of this interpreter) from start to end."""

from pathlib import Path

import nbformat
import numpy as np
import pandas as pd
import pytest
import xarray as xr
from nbclient import NotebookClient

NOTEBOOK = Path(__file__).resolve().parents[1] / "examples" / "quickstart.ipynb"


def _code_cells(nb):
    return [c for c in nb.cells if c.cell_type == "code"]


def test_the_notebook_is_committed_without_outputs():
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(nb)
    assert all(c.outputs == [] and c.execution_count is None for c in _code_cells(nb))


@pytest.fixture(scope="module")
def executed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("quickstart")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    client = NotebookClient(
        nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(folder)}}
    )
    client.execute()  # raises CellExecutionError on the first failing cell
    return nb, folder


def test_the_notebook_runs_plots_compares_and_exports(executed):
    nb, folder = executed
    outputs = [c.outputs for c in _code_cells(nb)]
    shown = [o for cell in outputs for o in cell if o.output_type == "execute_result"]
    assert shown[0]["data"]["text/plain"].startswith("<leolink.Result: 7 UTs x 60 epochs")
    assert any("image/png" in o["data"] for o in shown)  # the SNR/SINR figure
    compare = next(o["data"]["text/plain"] for o in shown if "hysteresis" in str(o["data"]))
    assert "max_snr" in compare and "beam handovers" in compare
    trace = pd.read_csv(folder / "quickstart_out" / "trace.csv")
    with xr.open_dataset(folder / "quickstart_out" / "paper.nc", engine="scipy") as ds:
        wide = trace.pivot(index="time_s", columns="ut_id", values="snr_db")
        np.testing.assert_array_equal(ds["snr_db"].to_numpy(), wide.to_numpy())
        assert ds["snr_db"].attrs["units"] == "dB"
        assert ds["population"].to_numpy().tolist()[5] == "car"
