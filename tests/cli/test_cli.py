"""End-to-end tests of the ``rdea-lab`` command line (rdea_lab.cli.main).

Every test checks the command's output against the paper's tables or against
hand calculations from the numbers the command itself prints (never against
numbers copied from an earlier run). What only a real process shows (the
``python -m rdea_lab.cli.main`` entry point, the exit status through
``sys.exit``, nothing else on stderr, the help pages) runs in a subprocess, as
a user would (`rdea`); the numbers and the one-line refusals run in this
process (`rdea_here`) through the same `rdea_lab.cli.errors.run` that the
entry point exits with, which saves a second of start-up per call.

Reference: Prechtl et al., Smart Mater. Struct. (2021), doi:10.1088/1361-665X/ac34be.
"""

import contextlib
import csv
import io
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rdea_lab.cli.errors import run as run_cli
from rdea_lab.cli.main import cli

ROOT = Path(__file__).resolve().parents[2]

#: Vacuum permittivity, CODATA 2018 [F/m]. scipy >= 1.15 uses CODATA 2022
#: (8.8541878188e-12), 6.8e-10 relative away; see REL_EPS0.
EPS0 = 8.8541878128e-12
#: Tolerance for anything proportional to eps0: covers the CODATA 2018/2022
#: revision of eps0 (6.8e-10 relative) and nothing more.
REL_EPS0 = 1e-9
MM, UM = 1e-3, 1e-6

# Table 2 of the paper (radii in mm) and Table 1 (L1, L1e in mm)
TABLE2 = {
    "specimen1.yaml": dict(id="specimen-1", Rie=0.600, Roe=1.206, Ro=1.326, L1=34, L1e=29),
    "specimen2.yaml": dict(id="specimen-2", Rie=0.600, Roe=1.615, Ro=1.732, L1=34, L1e=29),
    "specimen3.yaml": dict(id="specimen-3", Rie=0.600, Roe=1.206, Ro=1.326, L1=91, L1e=86),
}
L3 = 48 * UM

# passive core of Section 3.4 and the material of ref. [36] (ERRATA.md)
PASSIVE = dict(Ri=0.0, Rie=0.81 * MM, Roe=1.76 * MM, Ro=1.8 * MM, L1=34 * MM)
C10, C20, C30, EPS_R = 241e3, -33.2e3, 20.1e3, 2.8
CURVE = ["curve", "--specimen", "specimens/passive_core.yaml", "--params", "params/rizzello2020.yaml"]
STRETCH = np.linspace(1.0, 1.5, 11)  # what --stretch 1:1.5:11 means


def rdea(*args):
    """Run ``python -m rdea_lab.cli.main *args`` from the repository root."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("RDEA_LAB_DEBUG", None)  # a user error must never print a traceback anyway
    return subprocess.run(
        [sys.executable, "-m", "rdea_lab.cli.main", *map(str, args)],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=120,
    )


def rdea_here(*args):
    """``rdea-lab *args`` in this process, from the repository root: what `rdea` returns, without the start-up."""
    out, err = io.StringIO(), io.StringIO()
    debug = os.environ.pop("RDEA_LAB_DEBUG", None)  # as in `rdea`
    try:
        with contextlib.chdir(ROOT), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = run_cli(cli, [str(a) for a in args])
    finally:
        if debug is not None:
            os.environ["RDEA_LAB_DEBUG"] = debug
    return subprocess.CompletedProcess(args, code, out.getvalue(), err.getvalue())


def ok_json(*args):
    proc = rdea_here(*args)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def su_stress_hand(l):
    """SU stress at 0 V by hand: ``2 l^2 W'(x) (1 - l^-3)``, x = I1 - 3 = l^2 + 2/l - 3."""
    l = np.asarray(l, float)
    x = l**2 + 2.0 / l - 3.0
    w1 = C10 + 2.0 * C20 * x + 3.0 * C30 * x**2
    return 2.0 * l**2 * w1 * (1.0 - l**-3)


# ------------------------------------------------------------------ geometry
@pytest.fixture(scope="module", params=sorted(TABLE2))
def geometry_json(request):
    return request.param, ok_json("geometry", f"specimens/{request.param}", "--json")


def test_geometry_json_keys(geometry_json):
    _, out = geometry_json
    keys = {"Ri", "Rie", "Roe", "Ro", "eta_a", "eta_b", "eta_c", "alpha_e1", "C0"}
    assert keys <= set(out)
    assert all(isinstance(out[k], float) for k in keys)


def test_geometry_radii_match_table2(geometry_json):
    name, out = geometry_json
    ref = TABLE2[name]
    assert out["id"] == ref["id"]
    assert out["Ri"] == 0.0  # eq. (52): the spiral starts on the axis
    for k in ("Rie", "Roe", "Ro"):
        # ERRATA.md: the corrected appendix reproduces Table 2 within 0.5 %
        # (a small systematic offset remains, plus Table 2's 3-decimal rounding)
        assert out[k] == pytest.approx(ref[k] * MM, rel=5e-3), k


def test_geometry_fractions_and_coverage(geometry_json):
    name, out = geometry_json
    ref = TABLE2[name]
    # the three rings fill the roll; only float rounding of three ratios
    assert out["eta_a"] + out["eta_b"] + out["eta_c"] == pytest.approx(1.0, abs=1e-12)
    # alpha_e1 = L1e / L1 (eq. 13): 29/34 or 86/91; rel 1e-15 absorbs the
    # rounding of the mm -> m conversion of L1e and L1
    assert out["alpha_e1"] == pytest.approx(ref["L1e"] / ref["L1"], rel=1e-15)


def test_geometry_C0_by_hand(geometry_json):
    name, out = geometry_json
    ref = TABLE2[name]
    # C0 = eps0 eps_r alpha_e1 L1 pi (Roe^2 - Rie^2) / L3^2 (ERRATA.md, eq. 41)
    # from the radii the command printed (JSON floats round-trip exactly)
    hand = (EPS0 * 2.8 * out["alpha_e1"] * ref["L1"] * MM * math.pi
            * (out["Roe"] ** 2 - out["Rie"] ** 2) / L3**2)
    assert out["C0"] == pytest.approx(hand, rel=REL_EPS0)
    assert out["eps_r"] == 2.8  # the default is Table 1's permittivity


def test_geometry_eps_r_scales_C0():
    base = ok_json("geometry", "specimens/specimen2.yaml", "--json")
    other = ok_json("geometry", "specimens/specimen2.yaml", "--json", "--eps-r", "3.0")
    # C0 is linear in eps_r; the radii do not depend on it
    assert other["C0"] == pytest.approx(base["C0"] * 3.0 / 2.8, rel=1e-14)  # two roundings
    assert {k: other[k] for k in ("Rie", "Roe", "Ro")} == {k: base[k] for k in ("Rie", "Roe", "Ro")}


def test_geometry_text_mentions_id():
    proc = rdea("geometry", "specimens/specimen2.yaml")
    assert proc.returncode == 0, proc.stderr
    assert "specimen-2" in proc.stdout
    assert proc.stderr == ""


# --------------------------------------------------------------------- curve
@pytest.fixture(scope="module")
def curves():
    """``curve --json`` of the four models on the passive core at 0 and 3.5 kV."""
    return {m: ok_json(*CURVE, "--model", m, "--stretch", "1:1.5:11", "--voltage", "0,3.5kV", "--json")
            for m in ("su", "1r", "3r", "cr")}


def test_curve_json_structure(curves):
    for model, out in curves.items():
        assert out["model"] == model
        assert [c["voltage"] for c in out["curves"]] == [0.0, 3500.0]  # '3.5kV' in V
        for c in out["curves"]:
            assert {"voltage", "stretch", "sigma1", "force", "lambda2b", "capacitance", "converged"} <= set(c)
            for k in ("stretch", "sigma1", "force", "lambda2b", "capacitance", "converged"):
                assert len(c[k]) == 11, k
            assert c["converged"] == [True] * 11
            np.testing.assert_array_equal(c["stretch"], STRETCH)  # JSON floats round-trip


def test_curve_su_zero_volt_by_hand(curves):
    c0 = curves["su"]["curves"][0]
    l = np.array(c0["stretch"])
    # hand formula in its plain form vs the library's expm1 form: they differ by
    # float cancellation in (1 - l^-3) and x near l = 1 only (~1e-14 relative);
    # abs 1e-6 Pa (1e-12 of C10) for l = 1, where sigma1 is 0
    np.testing.assert_allclose(c0["sigma1"], su_stress_hand(l), rtol=1e-9, atol=1e-6)
    # force = sigma1 pi (Ro^2 - Ri^2) / lambda1 (ERRATA.md); a few roundings
    area = math.pi * (PASSIVE["Ro"] ** 2 - PASSIVE["Ri"] ** 2)
    np.testing.assert_allclose(c0["force"], np.array(c0["sigma1"]) * area / l, rtol=1e-12, atol=0)
    # eq. (41): C = C0 lambda1, alpha_e1 = 1 for this card
    C0 = EPS0 * EPS_R * 1.0 * PASSIVE["L1"] * math.pi * (PASSIVE["Roe"] ** 2 - PASSIVE["Rie"] ** 2) / L3**2
    np.testing.assert_allclose(c0["capacitance"], C0 * l, rtol=REL_EPS0, atol=0)
    # SU keeps the uniaxial hoop stretch lambda1^-1/2 (eq. 36)
    np.testing.assert_allclose(c0["lambda2b"], l**-0.5, rtol=1e-14)


def test_curve_su_maxwell_stress(curves):
    zero, high = curves["su"]["curves"]
    l = np.array(zero["stretch"])
    v = high["voltage"]
    eta_b = (1.76**2 - 0.81**2) / 1.8**2  # eq. (11), passive core
    # eq. (39) with alpha_e1 = 1 and E = sqrt(lambda1) v / L3
    maxwell = 0.5 * eta_b * EPS0 * EPS_R * (np.sqrt(l) * v / L3) ** 2
    drop = np.array(zero["sigma1"]) - np.array(high["sigma1"])
    # eps0 revision dominates; the subtraction loses at most ~1e-10 Pa of ~5e4 Pa
    np.testing.assert_allclose(drop, maxwell, rtol=REL_EPS0, atol=0)


def test_curve_models_agree_at_zero_volt(curves):
    su = np.array(curves["su"]["curves"][0]["sigma1"])
    for model in ("1r", "3r", "cr"):
        other = np.array(curves[model]["curves"][0]["sigma1"])
        # at 0 V the 1R and 3R equilibria are the uniaxial state of SU (Section 3.4:
        # "at 0 V all three coincide"); 1e-8 leaves room for the iterative solvers'
        # stopping tolerance; abs 1e-3 Pa (4e-9 of C10) for lambda1 = 1 where sigma1 = 0
        np.testing.assert_allclose(other, su, rtol=1e-8, atol=1e-3, err_msg=model)


def test_curve_cr_is_su_on_a_solid_roll(curves):
    """The passive core has Ri = 0: CR pins r_i = 0 (an open hole costs infinite energy), so it is
    the SU state at every voltage, to rounding (docs/models-cr.md)."""
    for zero_or_high in (0, 1):
        cr = np.array(curves["cr"]["curves"][zero_or_high]["sigma1"])
        su = np.array(curves["su"]["curves"][zero_or_high]["sigma1"])
        np.testing.assert_allclose(cr, su, rtol=1e-9, atol=1e-6)


def test_curve_csv_rows():
    proc = rdea(*CURVE, "--model", "su", "--stretch", "1:1.5:11", "--voltage", "0,3.5kV", "--csv")
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.reader(io.StringIO(proc.stdout)))
    header, body = rows[0], rows[1:]
    assert header[:2] == ["voltage_V", "stretch"] and "force_N" in header
    assert len(body) == 2 * 11
    assert all(len(r) == len(header) for r in body)
    assert sorted({float(r[0]) for r in body}) == [0.0, 3500.0]
    col = header.index("sigma1_Pa")
    zero = [r for r in body if float(r[0]) == 0.0]
    # CSV writes repr floats, so the same hand check as the JSON holds
    np.testing.assert_allclose([float(r[col]) for r in zero],
                               su_stress_hand([float(r[1]) for r in zero]), rtol=1e-9, atol=1e-6)


# ---------------------------------------------------------------- bad input
def _bad_card(tmp_path):
    text = (ROOT / "rdea_lab" / "data" / "specimens" / "specimen2.yaml").read_text()
    assert "L3: 48 um" in text
    path = tmp_path / "negative_thickness.yaml"
    path.write_text(text.replace("L3: 48 um", "L3: -48 um"))
    return path


def _bad_params(tmp_path):
    text = (ROOT / "rdea_lab" / "data" / "params" / "rizzello2020.yaml").read_text()
    assert "C10: 241 kPa" in text
    path = tmp_path / "c10_zero.yaml"
    path.write_text(text.replace("C10: 241 kPa", "C10: 0 kPa"))
    return path


BAD = {
    # id: (arguments, words the one-line message must contain)
    "missing-card": (["geometry", "specimens/no_such_card.yaml"], ["no_such_card.yaml"]),
    "missing-card-curve": (["curve", "--specimen", "specimens/no_such_card.yaml", "--params",
                            "params/rizzello2020.yaml"], ["no_such_card.yaml"]),
    "model-4r": ([*CURVE, "--model", "4r"], ["--model", "4r"]),
    "stretch-below-1": ([*CURVE, "--stretch", "0.5:1:3"], ["--stretch", "0.5:1:3"]),
    "stretch-malformed": ([*CURVE, "--stretch", "1:2"], ["--stretch", "1:2"]),
    "stretch-zero-samples": ([*CURVE, "--stretch", "1:2:0"], ["--stretch", "1:2:0"]),
    "voltage-abc": ([*CURVE, "--voltage", "abc"], ["--voltage", "abc"]),
    "voltage-kg": ([*CURVE, "--voltage", "3 kg"], ["--voltage", "3 kg"]),
    "json-and-csv": ([*CURVE, "--json", "--csv"], ["--json", "--csv"]),
    "negative-thickness": (["geometry", _bad_card], ["negative_thickness.yaml", "L3"]),
    "eps-r-below-1": (["geometry", "specimens/specimen2.yaml", "--eps-r", "0.5"], ["--eps-r", "0.5"]),
    "C10-zero": (["curve", "--specimen", "specimens/passive_core.yaml", "--params", _bad_params],
                 ["c10_zero.yaml", "C10"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_exits_2_with_one_line(case, tmp_path):
    args, words = BAD[case]
    args = [a(tmp_path) if callable(a) else a for a in args]
    proc = rdea_here(*args) if case != "missing-card" else rdea(*args)  # one of them as a real process
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].strip(), proc.stderr
    assert "Traceback" not in proc.stderr
    assert proc.stdout == ""
    for word in words:
        assert word in lines[0], (word, lines[0])


# ------------------------------------------------------------ help and bench
def test_no_command_is_help_or_one_short_line():
    proc = rdea()
    assert proc.returncode in (0, 2)
    if proc.returncode == 0:  # help on stdout
        assert "Usage" in proc.stdout
    else:  # a user mistake: one short line that says what is missing, not the help page
        lines = proc.stderr.splitlines()
        assert len(lines) == 1 and "Commands:" not in lines[0]


@pytest.mark.parametrize("command", [[], ["geometry"], ["curve"], ["bench"]],
                         ids=["rdea-lab", "geometry", "curve", "bench"])
def test_help_has_example(command):
    proc = (rdea if not command else rdea_here)(*command, "--help")  # the top-level help in a real process
    assert proc.returncode == 0, proc.stderr
    assert "Example" in proc.stdout


@pytest.mark.slow  # 35 s here even at these sizes (the calibration and path benches keep their own sizes)
def test_bench_json():
    proc = rdea("bench", "--samples", 1000, "--baseline-samples", 10, "--repeat", 1, "--no-vhb", "--steps", 200,
                "--no-compile-probe", "--json")  # a process of its own: bench imports benchmarks/ onto sys.path
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert set(out["samples_per_s"]) >= {"su", "1r", "3r", "cr"}
    for model in ("su", "3r"):  # the per-sample step: median and p99 of 200 calls, and its ratio to the block twin
        lat = out["step_latency_us"][model]
        assert 0 < lat["median"] <= lat["p99"] and lat["steps"] == 200 and lat["ratio"] > 0
    for level in ("kernel", "solve"):
        assert all(out["kernels"][level][m]["ratio"] > 0 for m in ("su", "1r", "3r", "cr"))
    assert out["compile_s"] is None
    assert all(out["samples_per_s"][m] > 0 for m in ("su", "1r", "3r", "cr"))
    assert out["speedup_3r_vs_fsolve"] > 0
    # the fast 3R solver and the fsolve baseline solve the same equations (27);
    # 1e-6 is far above both solvers' convergence tolerances
    assert 0 <= out["max_rel_diff_3r_vs_fsolve"] < 1e-6
