"""Tests of rdea_lab.specs.truth (truth files) and rdea_lab.emulator.truth (true geometry)."""

import json

import pytest
import yaml

from .helpers import ROOT
from rdea_lab.emulator import true_geometry
from rdea_lab.physics.geometry import geometry_from_card
from rdea_lab.specs import SpecError, load_params, specimen_from_mapping
from rdea_lab.specs.truth import dump_truth, load_truth, truth_from_mapping, truth_from_yaml, truth_json

SHIPPED = ROOT / "rdea_lab" / "data" / "truth" / "paper2021.yaml"


def shipped_mapping():
    return yaml.safe_load(SHIPPED.read_text(encoding="utf-8"))


def test_shipped_truth_in_si(truth):
    assert (truth.name, truth.model, truth.seed) == ("paper2021-emulator", "cr", 2021)
    m = truth.material
    # kPa integers parse exactly; the material is a ParameterSet like params/*.yaml
    assert (m.C10, m.C20, m.C30, m.eps_r) == (242e3, -69e3, 47e3, 2.8)
    assert m.law == "finite_strain"
    assert [(b.mu, b.eta) for b in m.branches] == [(2757e3, pytest.approx(28.67e3, rel=1e-15)), (200e3, 300e3)]
    assert m.eta_v0 == 0.0
    e = truth.effects
    assert (e.passive_ends, e.passive_stiffness, e.fringe_capacitance) == (True, 1.0, True)
    assert e.clamp_compliance == pytest.approx(20e-6, rel=1e-15)
    assert (e.mullins.max_softening, e.mullins.energy_scale) == (0.05, 30e3)
    assert truth.instrument.force_drift == pytest.approx(0.5e-3 / 60.0, rel=1e-15)
    f = truth.radii_factors
    assert (f.Ri, f.Rie, f.Roe, f.Ro) == (1.0, 1.02, 0.985, 1.01)
    i = truth.instrument
    assert i.force_noise == pytest.approx(4e-3, rel=1e-15) and i.force_offset == pytest.approx(8e-3, rel=1e-15)
    assert i.actuator_lag == pytest.approx(4e-3, rel=1e-15) and i.amplifier_bandwidth == 300.0
    assert i.parasitic_capacitance == pytest.approx(25e-12, rel=1e-15)
    assert i.capacitance_noise == pytest.approx(0.5e-12, rel=1e-15)
    assert i.breakdown_field == pytest.approx(100e6, rel=1e-15)


def test_material_part_is_a_parameter_set_with_the_same_checks(truth):
    # the first branch and the Yeoh part are Table 3, as in params/paper2021_table3.yaml
    table3 = load_params(ROOT / "rdea_lab" / "data" / "params" / "paper2021_table3.yaml")
    assert (truth.material.C10, truth.material.C20, truth.material.C30) == (table3.C10, table3.C20, table3.C30)
    # the first branch is Table 3's by the small-strain map k = 3 mu, eta(44) = 3 eta (same relaxation time)
    b, ref = truth.material.branches[0], table3.branches[0]
    assert 3.0 * b.mu == pytest.approx(ref.k, rel=1e-12)
    assert 3.0 * b.eta == pytest.approx(ref.eta, rel=2e-4) and b.eta / b.mu == pytest.approx(ref.eta / ref.k, rel=2e-4)


def test_round_trips(truth):
    assert truth_from_yaml(dump_truth(truth)) == truth
    text = truth_json(truth)
    assert "\n" not in text and text.isascii()
    assert truth_from_mapping(json.loads(text)) == truth


BAD = [
    ("instrument", "force_noise", "-1 mN", "instrument.force_noise", ">= 0"),
    ("instrument", "force_offset", "-8 mN", "instrument.force_offset", ">= 0"),
    ("instrument", "actuator_lag", "-1 ms", "instrument.actuator_lag", ">= 0"),
    ("instrument", "actuator_lag", "4", "instrument.actuator_lag", "no unit"),
    ("instrument", "amplifier_bandwidth", "0 Hz", "instrument.amplifier_bandwidth", "> 0"),
    ("instrument", "parasitic_capacitance", "-1 pF", "instrument.parasitic_capacitance", ">= 0"),
    ("instrument", "capacitance_noise", "-1 pF", "instrument.capacitance_noise", ">= 0"),
    ("instrument", "breakdown_field", "0 V/um", "instrument.breakdown_field", "> 0"),
    ("instrument", "breakdown_field", "100 V", "instrument.breakdown_field", "electric field"),
    ("radii_factors", "Roe", 1.5, "radii_factors.Roe", "outside (0.5, 1.5)"),
    ("radii_factors", "Rie", 0.5, "radii_factors.Rie", "outside (0.5, 1.5)"),
    ("radii_factors", "R0", 1.0, "radii_factors.R0", "unknown key"),
    ("yeoh", "C20", "-500 kPa", "yeoh.C20", "too negative"),
    (None, "model", "4r", "model", "not one of su, 1r, 3r"),
    (None, "seed", -1, "seed", "integer from 0 to 2**63 - 1"),
    (None, "seed", 1.5, "seed", "integer from 0 to 2**63 - 1"),
    (None, "seed", 2**64, "seed", "integer from 0 to 2**63 - 1"),
    (None, "eps_r", 0.5, "eps_r", ">= 1"),
    (None, "noise", "4 mN", "noise", "unknown key"),
    ("instrument", "force_drift", "0.5 mN", "instrument.force_drift", "force rate"),
    ("effects", "clamp_compliance", "-1 um/N", "effects.clamp_compliance", ">= 0"),
    ("effects", "clamp_compliance", "20 um", "effects.clamp_compliance", "compliance"),
    ("effects", "passive_stiffness", 0, "effects.passive_stiffness", "outside [0.5, 5]"),
    ("effects", "passive_stiffness", 6, "effects.passive_stiffness", "outside [0.5, 5]"),
    ("effects", "clamp_compliance", "200 um/N", "effects.clamp_compliance", "<="),
    ("effects", "passive_ends", "maybe", "effects.passive_ends", "maybe"),
    ("effects", "mullins", {"max_softening": 1.5, "energy_scale": "30 kPa"}, "effects.mullins.max_softening",
     "not in (0, 1)"),
    ("effects", "mullins", {"max_softening": 0.05, "energy_scale": "0 kPa"}, "effects.mullins.energy_scale", "> 0"),
    ("effects", "hysteresis", True, "effects.hysteresis", "unknown key"),
]


@pytest.mark.parametrize("section, key, value, field, words", BAD, ids=[f"{b[3]}={b[2]}" for b in BAD])
def test_bad_field_names_file_and_field(tmp_path, section, key, value, field, words):
    data = shipped_mapping()
    (data[section] if section else data)[key] = value
    path = tmp_path / "bad_truth.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(SpecError) as info:
        load_truth(path)
    err = info.value
    assert (err.source, err.field) == (str(path), field)
    assert words in err.message
    assert str(err).startswith(f"{path}: {field}: ") and "\n" not in str(err)


def test_missing_instrument_key(tmp_path):
    data = shipped_mapping()
    del data["instrument"]["breakdown_field"]
    with pytest.raises(SpecError, match=r"instrument\.breakdown_field: missing required key"):
        truth_from_mapping(data, "t.yaml")


def test_true_geometry_scales_the_radii(card, truth):
    nominal = geometry_from_card(card)
    geom = true_geometry(card, truth)
    assert (geom.Ri, geom.L1, geom.L1e, geom.L3) == (nominal.Ri, nominal.L1, nominal.L1e, nominal.L3)
    assert geom.Rie == nominal.Rie * 1.02 and geom.Roe == nominal.Roe * 0.985 and geom.Ro == nominal.Ro * 1.01


def test_factors_that_unorder_the_radii_name_the_factor(truth):
    # a thin active ring: Rie = 1.0 mm, Roe = 1.1 mm; Rie x 1.2 = 1.2 mm > Roe
    card = specimen_from_mapping({"id": "thin", "kind": "roll", "L1": "34 mm", "L1e": "29 mm", "L3": "48 um",
                                  "radii": {"Ri": "0 mm", "Rie": "1.0 mm", "Roe": "1.1 mm", "Ro": "1.2 mm"}})
    data = json.loads(truth_json(truth))
    data["radii_factors"] = {"Rie": 1.2}
    with pytest.raises(SpecError) as info:
        true_geometry(card, truth_from_mapping(data), source="truth/x.yaml")
    assert (info.value.source, info.value.field) == ("truth/x.yaml", "radii_factors.Roe")
    assert "Rie x 1.2" in info.value.message and "Ri <= Rie < Roe <= Ro" in info.value.message
    data["radii_factors"] = {"Ro": 0.9}  # Ro x 0.9 = 1.08 mm < Roe = 1.1 mm
    with pytest.raises(SpecError, match=r"radii_factors\.Ro: with thin, Ro x 0\.9 = 1\.08 mm is smaller than Roe"):
        true_geometry(card, truth_from_mapping(data), source="truth/x.yaml")
