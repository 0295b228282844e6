"""The first ten minutes (issue 24): the base install without its extras, a wheel outside the checkout,
and the README's two commands in a fresh clone.

The slow ones build and install the package for real (a wheel into a fresh virtual environment, an
editable install of a fresh clone); they see this interpreter's packages (``--system-site-packages``)
so that nothing but rdea-lab itself is downloaded or built.
"""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Every optional dependency of the base install (the extras [fast], [design], [monitor], [import]).
EXTRA_MODULES = ("numba", "llvmlite", "dask", "distributed", "bokeh", "SALib", "nptdms")


def without_extras(argv, cwd, blocked=EXTRA_MODULES, timeout=600, then=None):
    """``rdea-lab ARGV`` (or the code ``then``) in a fresh interpreter in which the ``blocked`` modules
    cannot be imported (as on a machine where only the base install is)."""
    code = textwrap.dedent(f"""
        import sys
        class Hiding:  # every finder answers "no such module" for the blocked names, as if not installed
            def __init__(self, inner):
                self.inner = inner
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in {tuple(blocked)!r}:
                    return None
                return self.inner.find_spec(name, path, target)
            def __getattr__(self, attr):
                return getattr(self.inner, attr)
        sys.meta_path[:] = [Hiding(f) for f in sys.meta_path]
    """) + (textwrap.dedent(then) if then else f"from rdea_lab.cli.main import main\nmain({list(argv)!r})\n")
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True, timeout=timeout)


@pytest.mark.parametrize("argv, extra", [
    (["design", "stroke_spring", "--synchronous"], "design"),
    (["import", "x.tdms", "--format", "tdms", "--map", "time=g/t,position=g/x,force=g/f", "--specimen", "specimen2",
      "--protocol-kind", "tensile"], "import"),
    (["monitor", ".", "--no-browser"], "monitor"),
])
def test_a_missing_extra_is_exit_2_with_the_pip_command(tmp_path, argv, extra):
    if extra == "import":
        (tmp_path / "x.tdms").write_bytes(b"TDSm" + bytes(60))
    proc = without_extras(argv, tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and f"python3 -m pip install 'rdea-lab[{extra}]'" in lines[0], proc.stderr


@pytest.mark.slow
def test_the_base_install_runs_the_twin(tmp_path):
    """No numba: a twin run of 3R over a whole protocol runs on the numpy reference."""
    out = tmp_path / "run.nc"
    proc = without_extras(["run", "tensile_ramp_sine_2.6kV", "--specimen", "specimen2", "--backend", "twin",
                           "--model", "3r", "--out", str(out)], tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert out.is_file()


def test_without_numba_a_large_call_says_once_that_it_runs_at_numpy_speed(tmp_path):
    proc = without_extras([], tmp_path, then="""
        import numpy as np
        from rdea_lab.physics.geometry import geometry_from_card
        from rdea_lab.physics.models import solve
        from rdea_lab.specs import load_params, load_specimen
        geom = geometry_from_card(load_specimen("specimen2"))
        lam = np.linspace(1.0, 1.5, 20000)
        for _ in range(2):  # large enough for the compiled kernels (AUTO_MIN_SAMPLES), twice
            solve("1r", geom, load_params("paper2021_table3"), lam, np.full(lam.size, 2600.0))
        try:
            solve("1r", geom, load_params("paper2021_table3"), lam[:3], np.zeros(3), kernel="numba")
        except Exception as exc:
            print(type(exc).__name__, exc)
    """)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("rdea-lab[fast]") == 1, proc.stderr  # the note, once
    assert proc.stdout.startswith("MissingExtra ") and "rdea-lab[fast]" in proc.stdout  # asked for: refused


@pytest.mark.slow
def test_the_base_install_runs_reproduce(tmp_path):
    """`rdea-lab reproduce` with none of the extras importable (the emulator's finite-strain branches
    then run as plain Python): a complete report, the same table as with them."""
    proc = without_extras(["reproduce", "--no-speed", "--quiet", "--out", "r"], tmp_path, timeout=1800)
    assert proc.returncode == 0, proc.stderr[-3000:]
    rows = [line for line in proc.stdout.splitlines() if line.startswith("|")]
    committed = [line for line in (ROOT / "reports" / "paper2021" / "validation" / "table4.md").read_text()
                 .splitlines() if line.startswith("|")]
    assert rows == committed
    assert (tmp_path / "r" / "index.html").is_file()


def _venv(folder: Path) -> Path:
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(folder)], check=True)
    return folder / "bin"


def _complete(report: Path):
    for name in ("index.html", "params/calibrated.yaml", "validation/index.html", "validation/table4.md",
                 "validation/table4.csv", "speed/speed.md", "models/models.md"):
        assert (report / name).is_file(), name
    assert len(list((report / "datasets").rglob("*.nc"))) == 12
    assert len(list(report.rglob("*.png"))) >= 10


@pytest.mark.slow
def test_a_wheel_runs_reproduce_in_an_empty_folder_outside_the_checkout(tmp_path):
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w",
                    str(wheels), str(ROOT)], check=True, capture_output=True)
    (wheel,) = wheels.glob("rdea_lab-*.whl")
    bin_ = _venv(tmp_path / "venv")
    subprocess.run([bin_ / "python", "-m", "pip", "install", "-q", "--no-deps", str(wheel)], check=True,
                   capture_output=True)
    work = tmp_path / "empty"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    where = subprocess.run([bin_ / "python", "-c", "import rdea_lab; print(rdea_lab.__file__)"], cwd=work,
                           capture_output=True, text=True, env=env, check=True).stdout.strip()
    assert Path(where).is_relative_to(tmp_path / "venv"), where  # the wheel's package, not the checkout's
    proc = subprocess.run([bin_ / "rdea-lab", "reproduce", "--quiet"], cwd=work, capture_output=True, text=True,
                          env=env, timeout=1800)
    assert proc.returncode == 0, proc.stderr[-3000:]
    _complete(work / "rdea-lab-reproduce")
    assert "total" in proc.stdout.splitlines()[-1]  # the stage times end what it prints


def _readme_commands() -> list[str]:
    """The README's two set-up lines: install, then the main job; install, then the tests."""
    lines = [line.split("#")[0].strip() for line in (ROOT / "README.md").read_text().splitlines()]
    setup = [line for line in lines if line.startswith("python3 -m pip install") and "&&" in line]
    assert len(setup) == 2, setup
    return setup


@pytest.mark.slow
def test_the_readme_commands_in_order_in_a_fresh_clone(tmp_path):
    """The README's two commands, reproduce first, in a fresh clone of the committed tree: `git status`
    stays clean and the suite is green."""
    first, second = _readme_commands()
    assert first.endswith("&& rdea-lab reproduce") and second.endswith("&& python3 -m pytest -q")
    clone = tmp_path / "clone"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
    bin_ = _venv(tmp_path / "venv")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PATH"] = f"{bin_}{os.pathsep}{env['PATH']}"  # python3, rdea-lab: the venv's
    for command in (first, second):
        proc = subprocess.run(command, shell=True, cwd=clone, env=env, capture_output=True, text=True, timeout=3000)
        if proc.returncode != 0:  # the nested suite's failures by name (its -ra summary), then the output's tail
            named = [line for line in proc.stdout.splitlines() if line.startswith(("FAILED ", "ERROR "))]
            pytest.fail("\n".join([command, *named, proc.stdout[-4000:], proc.stderr[-2000:]]), pytrace=False)
        if command is first:
            where = subprocess.run(["python3", "-c", "import rdea_lab; print(rdea_lab.__file__)"], cwd=tmp_path,
                                   env=env, capture_output=True, text=True, check=True).stdout.strip()
            assert Path(where).is_relative_to(clone), where
            status = subprocess.run(["git", "status", "--porcelain"], cwd=clone, capture_output=True, text=True)
            assert status.stdout == "", status.stdout
            _complete(clone / "rdea-lab-reproduce")
    assert " passed" in proc.stdout.splitlines()[-1] and " failed" not in proc.stdout.splitlines()[-1]
    assert subprocess.run(["git", "status", "--porcelain"], cwd=clone, capture_output=True, text=True).stdout == ""
