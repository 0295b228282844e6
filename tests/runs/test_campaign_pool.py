"""`submit_campaign`: the campaign's runs as process-pool tasks give run_campaign's datasets."""

import numpy as np
import pytest

from rdea_lab.paths import data_dir
from rdea_lab.runs import run_campaign, submit_campaign
from rdea_lab.specs.campaign import load_campaign
from rdea_lab.store import open_run


@pytest.mark.slow
def test_pool_tasks_give_the_serial_campaigns_data(tmp_path):
    root = data_dir()
    campaign = tmp_path / "c.yaml"
    campaign.write_text(f"""name: two
root: {root}
backend: emulator
truth: truth/paper2021.yaml
seed: 11
out: datasets/two
specimens: [specimens/specimen1.yaml]
protocols: [protocols/tensile_ramp_sine_0V.yaml, protocols/capacitance_sweep.yaml]
""")
    spec, spec_root = load_campaign(campaign)
    serial = run_campaign(spec, spec_root, out_dir=tmp_path / "serial")
    from rdea_lab.reports.reproduce import process_pool

    with process_pool(2) as pool:  # (the safe start method: numba's threads may run in this process)
        # the second experiment submitted first: the order of the tasks changes nothing
        submitted = submit_campaign(spec, spec_root, pool, out_dir=tmp_path / "pool",
                                    first=lambda r: r.plan.kind == "capacitance")
        pooled = [f.result() for _, f in submitted]
    assert [r.status for r in serial + pooled] == ["complete"] * 4
    for a, b in zip(serial, pooled):
        x, y = open_run(a.path), open_run(b.path)
        assert x.attrs["seed"] == y.attrs["seed"]  # spec.seed + i, whichever process ran it
        for name in x.data_vars:  # one emulated rig per run or per specimen: the same numbers, bit for bit
            np.testing.assert_array_equal(x[name].values, y[name].values, err_msg=name)
