"""The example notebook runs end to end (its cells assert the comparison with SymPy's
LagrangesMethod: the same W and F, the same state at t = 5)."""

from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("sympy")
pytest.importorskip("matplotlib")
pytest.importorskip("scipy")

NOTEBOOK = Path(__file__).resolve().parent.parent / "examples" / "double_pendulum.ipynb"


def test_double_pendulum_notebook_executes():
    nb = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(
        nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(NOTEBOOK.parent)}}
    )
    client.execute()
    text = "\n".join(
        o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []) if o.get("output_type") == "stream"
    )
    assert "W − M: [0, 0, 0, 0]  F − f: [0, 0]" in text
    assert "largest difference" in text
    # The equations were rendered as LaTeX.
    latex = [o for c in nb.cells for o in c.get("outputs", []) if "text/latex" in o.get("data", {})]
    assert len(latex) >= 5
