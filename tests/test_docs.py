"""The docs site builds with `mkdocs build --strict` and not one warning; it documents every public name.

mkdocs and mkdocstrings-python come with the [docs] extra, which [test] pulls in. The build reads the
docstrings of this checkout (mkdocs.yml: ``paths: [.]``) and takes a few seconds.
"""

import inspect
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def test_docs_build_strict_without_warnings(tmp_path):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file",
                           str(ROOT / "mkdocs.yml"), "--site-dir", str(tmp_path / "site")],
                          check=False, cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"mkdocs build --strict failed (python3 -m pip install -e '.[docs]'?):\n{log}"
    warnings = [line for line in log.splitlines() if "WARNING" in line or "ERROR" in line]
    assert not warnings, "\n".join(warnings)
    api = (tmp_path / "site" / "api" / "index.html").read_text(encoding="utf-8")
    assert 'id="rdea_lab.runs.app.run_protocol"' in api  # mkdocstrings rendered the docstrings


def test_api_reference_lists_every_public_name():
    import rdea_lab.api

    text = (DOCS / "api.md").read_text(encoding="utf-8")
    listed = {line.split()[1].rsplit(".", 1)[1] for line in text.splitlines() if line.startswith("::: ")}
    public = set(rdea_lab.api.__all__) - {"__version__"}
    assert public | {"RdeaAccessor"} <= listed  # and ds.rdea
    # Beyond the public names, only what a public call takes or returns (its results, budget, monitor).
    said = " ".join(f"{_signature(getattr(rdea_lab.api, n))} {inspect.getdoc(getattr(rdea_lab.api, n))}"
                    for n in public)
    assert all(re.search(rf"\b{name}\b", said) for name in listed - public - {"RdeaAccessor"}), listed - public


def _signature(obj):
    try:
        return inspect.signature(obj)
    except (TypeError, ValueError):
        return ""


def test_a_guide_page_per_command():
    from rdea_lab.cli.main import cli

    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    for name in cli.commands:
        page = DOCS / "guide" / f"{name}.md"
        assert page.is_file(), page
        assert f"guide/{name}.md" in nav
        assert page.read_text(encoding="utf-8").startswith(f"# rdea-lab {name}\n")
