"""Tests of rdea_lab.specs.specimen: specimen cards in both geometry forms."""

import copy
from pathlib import Path

import pytest
from pydantic import ValidationError

from rdea_lab.specs import (
    Membrane,
    Radii,
    SpecError,
    SpecimenCard,
    dump_specimen,
    load_specimen,
    specimen_from_mapping,
    specimen_from_yaml,
)

SPECIMENS = Path(__file__).resolve().parents[2] / "rdea_lab" / "data" / "specimens"
MM, UM = 1e-3, 1e-6
# Every value is a short decimal parsed with decimal prefixes, so it is the
# float nearest to the SI value; rel=1e-15 only absorbs the rounding of the
# products on the right-hand side (e.g. 34 * 1e-3).
TOL = dict(rel=1e-15, abs=0.0)

# Table 1 of the paper, in mm (L3 in um)
TABLE1 = {
    "specimen1.yaml": dict(id="specimen-1", L1=34, L2=58, L3=48, L1e=29, Lp1=10, L2e=38),
    "specimen2.yaml": dict(id="specimen-2", L1=34, L2=99, L3=48, L1e=29, Lp1=10, L2e=76),
    "specimen3.yaml": dict(id="specimen-3", L1=91, L2=58, L3=48, L1e=86, Lp1=10, L2e=38),
}
# Section 3.4 of the paper, radii in mm
CORES = {
    "hollow_core.yaml": dict(id="hollow-core", Ri=0.86, Rie=0.88, Roe=1.76, Ro=1.8),
    "active_core.yaml": dict(id="active-core", Ri=0.0, Rie=0.088, Roe=1.76, Ro=1.8),
    "passive_core.yaml": dict(id="passive-core", Ri=0.0, Rie=0.81, Roe=1.76, Ro=1.8),
}
ALL_CARDS = sorted(TABLE1) + sorted(CORES)


@pytest.mark.parametrize("name", sorted(TABLE1))
def test_table1_cards(name):
    row = TABLE1[name]
    card = load_specimen(SPECIMENS / name)
    assert (card.id, card.kind, card.form, card.radii) == (row["id"], "roll", "membrane", None)
    m = card.membrane
    for key in ("L1", "L2", "L1e", "Lp1", "L2e"):
        assert getattr(m, key) == pytest.approx(row[key] * MM, **TOL), key
    assert m.L3 == pytest.approx(48 * UM, **TOL)
    assert m.Ri == 0.0  # default: the spiral starts at the axis, Eq. (52)
    assert m.Lp2 == pytest.approx((row["L2"] - row["Lp1"] - row["L2e"]) * MM, rel=1e-12)
    assert (card.L1, card.L1e, card.L3) == (m.L1, m.L1e, m.L3)
    assert "Table 1" in card.source


@pytest.mark.parametrize("name", sorted(CORES))
def test_section34_cores(name):
    row = CORES[name]
    card = load_specimen(SPECIMENS / name)
    assert (card.id, card.form, card.membrane) == (row["id"], "radii", None)
    for key in ("Ri", "Rie", "Roe", "Ro"):
        assert getattr(card.radii, key) == pytest.approx(row[key] * MM, **TOL), key
    assert card.L1 == card.L1e == pytest.approx(34 * MM, **TOL)  # alpha_e1 = 1
    assert card.L3 == pytest.approx(48 * UM, **TOL)
    assert "Section 3.4" in card.source


@pytest.mark.parametrize("name", ALL_CARDS)
def test_dump_then_load_gives_an_equal_card(name):
    card = load_specimen(SPECIMENS / name)
    text = dump_specimen(card)
    assert specimen_from_yaml(text) == card
    assert "L3: 48 um" in text and "mm" in text


def test_dump_round_trips_awkward_values():
    card = SpecimenCard(
        id="odd", kind="roll",
        membrane=Membrane(L1=0.1 / 3, L2=0.2, L3=4.9999e-5, L1e=0.01, Lp1=1 / 7 * 0.01, L2e=0.1, Ri=1e-7),
    )
    assert specimen_from_yaml(dump_specimen(card)) == card


def test_python_construction_takes_si_numbers_or_quantities():
    loaded = load_specimen(SPECIMENS / "passive_core.yaml")
    built = SpecimenCard(
        id="passive-core", kind="roll", description=loaded.description, source=loaded.source,
        radii=Radii(Ri=0.0, Rie="0.81 mm", Roe=1.76e-3, Ro=1.8e-3), L1=0.034, L1e="34 mm", L3=48e-6,
    )
    assert built == loaded


def test_from_mapping_and_from_yaml():
    mapping = {"id": "s", "kind": "roll",
               "membrane": {"L1": "34 mm", "L2": "58 mm", "L3": "48 um", "L1e": "29 mm", "Lp1": "10 mm",
                            "L2e": "38 mm"}}
    card = specimen_from_mapping(mapping)
    assert card.L3 == 48e-6
    assert specimen_from_yaml(dump_specimen(card)) == card


def test_boundaries_that_are_allowed():
    # rings a and c may vanish; L1e = L1; Lp1 + L2e = L2 (no outer passive layer)
    radii = Radii(Ri=0.5e-3, Rie=0.5e-3, Roe=1.8e-3, Ro=1.8e-3)
    card = SpecimenCard(id="edge", kind="roll", radii=radii, L1=0.034, L1e=0.034, L3=48e-6)
    assert card.radii.Ri == card.radii.Rie
    # 0.1 + 0.2 > 0.3 in floats: a sum equal in decimal must still pass
    m = Membrane(L1="34 mm", L2="300 mm", L3="48 um", L1e="34 mm", Lp1="100 mm", L2e="200 mm")
    assert m.Lp1 + m.L2e > m.L2
    assert m.Lp2 == 0.0


def test_cards_are_frozen():
    card = load_specimen(SPECIMENS / "specimen1.yaml")
    with pytest.raises(ValidationError):
        card.id = "other"


# ---------------------------------------------------------------- errors
MEMBRANE = {"id": "s", "kind": "roll",
            "membrane": {"L1": "34 mm", "L2": "58 mm", "L3": "48 um", "L1e": "29 mm", "Lp1": "10 mm", "L2e": "38 mm"}}
RADII = {"id": "s", "kind": "roll", "radii": {"Ri": "0 mm", "Rie": "0.81 mm", "Roe": "1.76 mm", "Ro": "1.8 mm"},
         "L1": "34 mm", "L1e": "34 mm", "L3": "48 um"}


def _set(base, path, value):
    data = copy.deepcopy(base)
    *parents, last = path.split(".")
    target = data
    for key in parents:
        target = target[key]
    if value is _DELETE:
        del target[last]
    else:
        target[last] = value
    return data


class _Delete:
    """The marker of a key to delete; its repr names it so test ids are the same in every process (xdist)."""

    def __repr__(self):
        return "<deleted>"


_DELETE = _Delete()

ERRORS = [
    # (base, path, value, field, match)
    (MEMBRANE, "membrane.L1", 34, "membrane.L1", r"'34' has no unit; give a length, e.g. '34 mm'"),
    (MEMBRANE, "membrane.L1", "34 mmm", "membrane.L1", r"unknown unit 'mmm'"),
    (MEMBRANE, "membrane.L3", "48 kg", "membrane.L3",
     r"'48 kg' is not a length; give it with a length unit, e.g. '48 um'"),
    (MEMBRANE, "membrane.L3", "-48 um", "membrane.L3", r"must be > 0 um, got -48 um"),
    (MEMBRANE, "membrane.L2", "0 mm", "membrane.L2", r"must be > 0 mm, got 0 mm"),
    (MEMBRANE, "membrane.Ri", "-1 mm", "membrane.Ri", r"must be >= 0 mm"),
    (MEMBRANE, "membrane.L2", "nan mm", "membrane.L2", r"not a finite number"),
    (MEMBRANE, "membrane.L2", None, "membrane.L2", r"no value given"),
    (MEMBRANE, "membrane.L2", True, "membrane.L2", r"True is not a quantity"),
    (MEMBRANE, "membrane.L2", _DELETE, "membrane.L2", r"missing required key 'L2'"),
    (MEMBRANE, "membrane.L4", "1 mm", "membrane.L4", r"unknown key 'L4'; allowed keys: L1, L2, L3, L1e, Lp1, L2e, Ri"),
    (MEMBRANE, "membrane.L1e", "35 mm", "membrane.L1e", r"L1e = 35 mm is longer than L1 = 34 mm; need L1e <= L1"),
    (MEMBRANE, "membrane.Lp1", "21 mm", "membrane.L2e", r"Lp1 \+ L2e = 21 mm \+ 38 mm is longer than L2 = 58 mm"),
    (MEMBRANE, "membrane", "34 mm", "membrane", r"expected a mapping with keys L1, L2"),
    (MEMBRANE, "L1", "34 mm", "L1", r"top-level L1 belongs to the 'radii' form"),
    (MEMBRANE, "radii", RADII["radii"], "radii", r"either as 'membrane' or as 'radii', not both"),
    (MEMBRANE, "membrane", _DELETE, "membrane", r"missing geometry"),
    (MEMBRANE, "colour", "red", "colour",
     r"unknown key 'colour'; allowed keys: id, kind, description, source, membrane, radii, L1, L1e, L3"),
    (MEMBRANE, "kind", "sheet", "kind", r"kind 'sheet' is not supported; allowed: roll"),
    (MEMBRANE, "id", "specimen 2", "id", r"not a valid name; use letters, digits"),
    (MEMBRANE, "id", "", "id", r"not a valid name"),
    (MEMBRANE, "id", 2, "id", r"expected a text string, got 2"),
    (MEMBRANE, "id", _DELETE, "id", r"missing required key 'id'"),
    (MEMBRANE, "description", None, "description", r"no value given"),
    (RADII, "radii.Ri", "0.9 mm", "radii.Rie", r"Rie = 0.81 mm is smaller than Ri = 0.9 mm; need Ri <= Rie"),
    (RADII, "radii.Roe", "0.81 mm", "radii.Roe",
     r"need Rie < Roe \(the active ring b must have a positive thickness\)"),
    (RADII, "radii.Ro", "1.7 mm", "radii.Ro", r"Ro = 1.7 mm is smaller than Roe = 1.76 mm; need Roe <= Ro"),
    (RADII, "radii.Ri", "-0.1 mm", "radii.Ri", r"must be >= 0 mm, got -0.1 mm"),
    (RADII, "radii.Ri", _DELETE, "radii.Ri", r"missing required key 'Ri'"),
    (RADII, "L3", _DELETE, "L3", r"missing required key 'L3' \(the 'radii' form needs L1, L1e and L3"),
    (RADII, "L3", "1 mm", "L3", r"not smaller than the active ring's thickness Roe - Rie = 0.95 mm"),
    (RADII, "L1e", "40 mm", "L1e", r"L1e = 40 mm is longer than L1 = 34 mm"),
]


@pytest.mark.parametrize("base, path, value, field, match", ERRORS, ids=[f"{e[1]}={e[2]!r}"[:40] for e in ERRORS])
def test_invalid_cards(base, path, value, field, match):
    with pytest.raises(SpecError, match=match) as info:
        specimen_from_mapping(_set(base, path, value), source="cards/s.yaml")
    err = info.value
    assert (err.source, err.field) == ("cards/s.yaml", field)
    assert str(err).startswith(f"cards/s.yaml: {field}: ")


def test_not_a_mapping():
    with pytest.raises(SpecError, match=r"<mapping>: expected a mapping of keys, got \[1, 2\]"):
        specimen_from_mapping([1, 2])


def test_non_text_key():
    with pytest.raises(SpecError, match=r"membrane\.1: key 1 is not a text string"):
        specimen_from_mapping(_set(MEMBRANE, "membrane", {1: "34 mm"}))


def test_python_construction_raises_spec_error():
    with pytest.raises(SpecError, match=r"^<python>: membrane\.L3: must be > 0 um, got -48 um$"):
        SpecimenCard(id="s", kind="roll", membrane=dict(L1=0.034, L2=0.058, L3=-48e-6, L1e=0.029, Lp1=0.01, L2e=0.038))
    with pytest.raises(SpecError, match=r"^<python>: L1: must be > 0 mm"):
        SpecimenCard(id="s", kind="roll", radii=Radii(Ri=0, Rie=1e-3, Roe=2e-3, Ro=2e-3), L1=-1.0, L1e=0.03, L3=4.8e-5)


def test_load_errors_name_the_file(tmp_path):
    missing = tmp_path / "nope.yaml"
    with pytest.raises(SpecError, match=r"nope\.yaml: file not found"):
        load_specimen(missing)
    with pytest.raises(SpecError, match=r": is a directory"):
        load_specimen(tmp_path)
    bad = tmp_path / "bad.yaml"
    bad.write_text("id: s\nkind: [roll\n")
    with pytest.raises(SpecError, match=r"bad\.yaml: not valid YAML: .*\(line \d+, column \d+\)"):
        load_specimen(bad)
