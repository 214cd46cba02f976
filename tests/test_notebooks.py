"""The notebook gallery (examples/*.ipynb) runs top to bottom (issue 24), so it never rots.

Each notebook is executed by nbclient in a fresh kernel (the repository's interpreter);
the cells' own asserts check their numbers (the paper example's error estimate, the
critical velocity between 27 and 28.5 m/s, one cache key for rpm and rad/s, the
diverged run).  Slow: several kernels and dozens of figures."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "examples").glob("*.ipynb"))


def test_the_gallery_covers_the_result_kinds() -> None:
    names = {p.stem for p in NOTEBOOKS}
    assert {"paper_example", "stability_map", "design_study", "forced_response"} <= names


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path: Path, tmp_path: Path) -> None:
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    book = nbformat.read(path, as_version=4)
    env = {"PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    os.environ.update({k: v for k, v in env.items() if k not in os.environ})
    client = nbclient.NotebookClient(
        book, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()
    code = [c for c in book.cells if c.cell_type == "code"]
    errors = [o for c in code for o in c.outputs if o.output_type == "error"]
    assert not errors
    media = [set(o.get("data", {})) for c in code for o in c.outputs]
    images = [m for m in media if m & {"image/png", "image/gif"}]
    assert images  # the figures were drawn
