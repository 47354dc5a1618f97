"""Every notebook runs top to bottom (small sample counts via KINEGRASP_NB_SCALE)."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import pytest

FOLDER = Path(__file__).resolve().parent.parent / "notebooks"
NOTEBOOKS = sorted(FOLDER.glob("*.ipynb"))


def _builder():
    """notebooks/build_notebooks.py, the notebooks' one source."""
    spec = importlib.util.spec_from_file_location("build_notebooks", FOLDER / "build_notebooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_committed_notebooks_are_one_clean_run_of_the_builders_sources():
    """The committed notebooks are exactly those notebooks/build_notebooks.py writes, each
    with the builder's cells (kind and source) and the outputs of one top-to-bottom run of
    them: every code cell executed once, in order (execution counts 1..N), no error output.
    A source edited in the builder without executing the notebook again fails here, as does
    a notebook run out of order or committed with a traceback."""
    nbformat = pytest.importorskip("nbformat")
    sources = _builder().NOTEBOOKS
    assert sorted(sources) == [p.name for p in NOTEBOOKS]
    for path in NOTEBOOKS:
        nb = nbformat.read(path, as_version=4)
        cells = [("markdown" if kind == "md" else "code", source)
                 for kind, source in sources[path.name]]
        assert [(c.cell_type, c.source) for c in nb.cells] == cells, path.name
        code = [c for c in nb.cells if c.cell_type == "code"]
        assert [c.execution_count for c in code] == list(range(1, len(code) + 1)), path.name
        errors = [o for c in code for o in c.outputs if o.output_type == "error"]
        assert not errors, (path.name, errors)


@pytest.mark.expensive
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_executes_without_error(path, tmp_path, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    monkeypatch.setenv("KINEGRASP_NB_SCALE", os.environ.get("KINEGRASP_NB_SCALE", "0.02"))
    nb = nbformat.read(path, as_version=4)
    # run in a scratch folder so the committed outputs and files stay untouched
    nbclient.NotebookClient(nb, timeout=900, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if o.get("output_type") == "error"]
    assert not errors
