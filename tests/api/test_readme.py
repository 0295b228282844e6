"""The README's notebook cell runs as written, and prints what the README says it prints."""

import contextlib
import io
import os
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_readme_notebook_cell(tmp_path):
    text = (ROOT / "README.md").read_text()
    section = text.split("## The library: a notebook cell", 1)[1]
    cell = re.search(r"```python\n(.*?)```", section, re.S)[1]
    claimed = re.search(r"print\(.*\)\s+# (.*)", cell)[1].strip()
    cell = cell.replace('out="demo.nc"', f'out={str(tmp_path / "demo.nc")!r}').replace(
        'rdea_lab.catalog(".")', f'table = rdea_lab.catalog({str(tmp_path)!r})')
    here = os.getcwd()
    os.chdir(ROOT)
    try:
        out = io.StringIO()
        scope = {}
        with contextlib.redirect_stdout(out):
            exec(compile(cell, "README.md", "exec"), scope)
    finally:
        os.chdir(here)
    assert out.getvalue().strip() == claimed
    assert list(scope["table"]["md.operator"]) == ["ana"]
    assert scope["fig"].axes  # a Figure was drawn
