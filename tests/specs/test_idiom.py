"""The one spec idiom (rdea_lab.specs.base.SpecModel): ``Kind.load``, ``Kind.from_yaml``, ``Kind.from_mapping``
and ``spec.dump``, the same for every kind, and the old functions as wrappers giving the same objects."""

from pathlib import Path

import pytest
import yaml

from rdea_lab.specs import (ParameterSet, ProtocolSpec, SpecError, SpecimenCard, TruthSpec, dump_params,
                            dump_protocol, dump_specimen, dump_truth, load_params, load_protocol, load_specimen,
                            load_truth, params_from_yaml, specimen_from_mapping)
from rdea_lab.specs.campaign import CampaignSpec, load_campaign
from rdea_lab.specs.study import Study, load_study
from rdea_lab.specs.target import Target, load_target

DATA = Path(__file__).resolve().parents[2] / "rdea_lab" / "data"
KINDS = [(SpecimenCard, "specimens", load_specimen, dump_specimen), (ParameterSet, "params", load_params, dump_params),
         (ProtocolSpec, "protocols", load_protocol, dump_protocol), (TruthSpec, "truth", load_truth, dump_truth)]
FILES = [(kind, path, load, dump) for kind, folder, load, dump in KINDS
         for path in sorted((DATA / folder).glob("*.yaml"))]


@pytest.mark.parametrize("kind, path, load, dump", FILES, ids=[f"{p.parent.name}/{p.name}" for _, p, _, _ in FILES])
def test_each_kind_loads_dumps_and_reads_back_through_the_base(kind, path, load, dump):
    spec = kind.load(path)
    assert spec == load(path) and spec.dump() == dump(spec)  # the old functions: the same object, the same text
    assert kind.from_yaml(spec.dump(), "x.yaml") == spec
    assert kind.from_mapping(yaml.safe_load(path.read_text()), str(path)) == spec


def test_a_packaged_name_loads_by_its_kind():
    assert SpecimenCard.load("specimens/specimen2.yaml") == load_specimen(DATA / "specimens" / "specimen2.yaml")


@pytest.mark.parametrize("kind", [SpecimenCard, ParameterSet, ProtocolSpec, TruthSpec, Study, Target])
def test_a_document_that_is_not_a_mapping_is_refused_naming_its_source(kind):
    with pytest.raises(SpecError, match=r"^a\.yaml: expected a mapping of keys, got \[1, 2\]$"):
        kind.from_mapping([1, 2], "a.yaml")
    with pytest.raises(SpecError, match=r"^b\.yaml: top level is a list"):
        kind.from_yaml("- 1\n", "b.yaml")


def test_errors_name_the_source_given():
    with pytest.raises(SpecError, match=r"^attr: yeoh\.C10: "):
        ParameterSet.from_yaml(dump_params(load_params(DATA / "params" / "paper2021_table3.yaml"))
                               .replace("C10: 242", "C10: -242"), "attr")
    assert params_from_yaml("name: x\nyeoh: {C10: 1 kPa, C20: 0 kPa, C30: 0 kPa}\neps_r: 3\n").C10 == 1e3
    with pytest.raises(SpecError, match=r"^<mapping>: "):
        specimen_from_mapping({"id": "x"})


def test_a_campaign_loads_with_its_inputs_found_and_its_folder():
    path = DATA / "campaigns" / "paper2021.yaml"
    spec = CampaignSpec.load(path)
    assert (spec, spec.folder) == load_campaign(path) and spec.origin == str(path)
    assert all(Path(p).is_absolute() for p in spec.specimens + spec.protocols)


def test_a_study_read_from_a_file_keeps_its_text_and_from_a_mapping_its_folder(tmp_path):
    path = DATA / "studies" / "stroke_spring.yaml"
    study = Study.load(path)
    assert study.text == path.read_text() and load_study(path).text == study.text
    again = Study.from_mapping(yaml.safe_load(path.read_text()), "elsewhere.yaml", folder=path.parent)
    assert again.text == "" and again.n == study.n and again.source == "elsewhere.yaml"
    with pytest.raises(SpecError, match=r"^elsewhere\.yaml: params: '\.\./params/paper2021_table3\.yaml' not found"):
        Study.from_mapping(yaml.safe_load(path.read_text()), "elsewhere.yaml", folder=tmp_path)


def test_a_target_reads_its_csv_from_its_folder():
    path = DATA / "targets" / "spring_stroke.yaml"
    target = Target.load(path)
    assert target.source == load_target(path).source and target.values.size == load_target(path).values.size
    assert target == target and target != load_target(path)  # compared as the object it is (arrays inside)


def test_a_kind_without_a_file_of_its_own_says_so():
    from rdea_lab.specs.specimen import Membrane

    card = load_specimen(DATA / "specimens" / "specimen2.yaml")
    with pytest.raises(NotImplementedError, match="Membrane is not written as a file of its own"):
        Membrane.dump(card.membrane)
