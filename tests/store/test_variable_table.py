"""The CF variable table: one implementation, in the specs (below the twin and the store that both write
datasets), and the same words the committed datasets were written with (issue 26)."""

import ast
import importlib.util
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import rdea_lab.specs.variables as table
from rdea_lab.store import schema
from rdea_lab.twin import simulate

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "rdea_lab"
DATA = PKG / "data"
#: Written by rdea-lab before the table moved (committed, emulated runs of the paper's campaign).
COMMITTED = sorted((ROOT / "datasets" / "paper2021").glob("*/*.nc"))
TABLE_NAMES = ("RUN_VARIABLES", "MODEL_VARIABLES", "OPTIONAL_RUN_VARIABLES", "SELFSENSE_VARIABLES", "FLAGS",
               "REFERENCES", "NO_INSTITUTION", "TIME_LONG_NAME", "TIME_ENCODING")


def test_the_twin_holds_no_copy_of_the_table():
    assert importlib.util.find_spec("rdea_lab.twin.cf") is None
    defined = []
    for path in sorted(PKG.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            targets = (node.targets if isinstance(node, ast.Assign) else [node.target]
                       if isinstance(node, ast.AnnAssign) else [])
            defined += [f"{path.relative_to(PKG)}: {t.id}" for t in targets
                        if isinstance(t, ast.Name) and t.id in TABLE_NAMES]
            if isinstance(node, ast.FunctionDef) and node.name in ("variable_attrs", "time_attrs", "global_attrs"):
                defined.append(f"{path.relative_to(PKG)}: def {node.name}")
    assert {d.split(":")[0] for d in defined} == {str(Path("specs") / "variables.py")}, defined


def test_the_store_takes_its_schema_from_the_specs_not_the_twin():
    tree = ast.parse((PKG / "store" / "schema.py").read_text())
    modules = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert not any("twin" in (m or "") for m in modules), modules
    for name in ("variable_attrs", "time_attrs", "global_attrs", "FLAGS", "REFERENCES", "OPTIONAL_RUN_VARIABLES"):
        assert getattr(schema, name) is getattr(table, name), name
    assert schema.VARIABLES is table.RUN_VARIABLES


@pytest.mark.parametrize("path", COMMITTED, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_the_committed_datasets_carry_the_tables_words(path):
    """Every variable of a run written before the move has exactly the attributes the table gives now."""
    with xr.open_dataset(path, decode_times=False) as ds:
        for name in ds.variables:
            attrs = dict(ds[name].attrs)
            want = table.time_attrs(ds.attrs["created"]) if name == "time" else table.variable_attrs(name)
            assert attrs == want, name


def test_a_twin_dataset_takes_its_attributes_from_the_table():
    t = np.linspace(0.0, 1.0, 11)
    ds = simulate(DATA / "specimens" / "specimen2.yaml", DATA / "params" / "paper2021_table3.yaml", t,
                  1.0 + 0.1 * t, 0.0, "su")
    for name in ds.data_vars:
        attrs, want = dict(ds[name].attrs), table.variable_attrs(name)
        assert attrs.keys() == want.keys(), name
        for key, value in want.items():
            np.testing.assert_array_equal(attrs[key], value)
    assert ds["model_status"].attrs["flag_meanings"].split()[0] == "ok"
    assert ds.attrs["references"] == table.REFERENCES
