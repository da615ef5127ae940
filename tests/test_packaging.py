"""The project's own files: environment.yml agrees with pyproject.toml, README and CI agree."""

import re
import tomllib
from pathlib import Path

import pytest
import yaml

from tests.conftest import REPO

CONDA_TO_PIP = {"matplotlib-base": "matplotlib"}


def _name(req: str) -> str:
    return re.split(r"[<>=!~;\[ ]", req.strip(), maxsplit=1)[0].lower()


def test_environment_yml_lists_the_same_packages_as_pyproject():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    wanted = {_name(r) for r in project["dependencies"]} | {
        _name(r) for r in project["optional-dependencies"]["dev"]
    }
    env = yaml.safe_load((REPO / "environment.yml").read_text())
    assert set(env) == {"name", "channels", "dependencies"}
    assert "conda-forge" in env["channels"]
    assert "python=3.11" in env["dependencies"]
    names = set()
    for dep in env["dependencies"]:
        if isinstance(dep, dict):  # the pip: sub-list
            names |= {_name(d) for d in dep["pip"] if not d.startswith("-e")}
        else:
            n = _name(dep.split("=")[0] if "=" in dep and "<" not in dep and ">" not in dep else dep)
            names.add(CONDA_TO_PIP.get(n, n))
    names -= {"python", "pip"}
    assert names == wanted, (names - wanted, wanted - names)


def _readme_commands():
    text = (REPO / "README.md").read_text()
    block = re.search(r"## Two commands.*?```bash\n(.*?)```", text, re.S).group(1)
    return [ln.strip() for ln in block.splitlines() if ln.strip() and not ln.startswith("#")]


def test_readme_has_exactly_two_commands_and_ci_runs_the_test_one():
    commands = _readme_commands()
    assert len(commands) == 2
    install_and_run, test = commands
    assert "scripts/setup.sh" in install_and_run and "repro all" in install_and_run
    assert "pytest" in (REPO / test.split()[-1]).read_text()
    ci = (REPO / ".ci/run").read_text()
    assert test in ci, "CI must run the README's test command"


def test_pytest_runs_nbval_over_notebooks():
    ini = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]
    assert "notebooks" in ini["testpaths"] and "--nbval " in ini["addopts"] + " "
    assert "--nbval-cell-timeout" in ini["addopts"]


def test_readme_library_example_runs():
    """The README's Python example is real code that runs on the embedded face."""
    text = (REPO / "README.md").read_text()
    code = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    ns: dict = {}
    exec(compile(code, "README.md", "exec"), ns)
    assert ns["vertices"].shape == (ns["face"].n_vertices, 3)


def test_readme_lists_every_registered_figure():
    from repro.experiments import registry

    text = (REPO / "README.md").read_text()
    missing = [name for name in registry() if f"`{name}`" not in text]
    assert not missing, f"README.md does not list {missing}"


def test_package_data_covers_every_file_the_package_ships():
    """Every tracked non-Python file under repro/ is matched by ``[tool.setuptools.package-data]``:
    a file left out works from a clone (editable install) and is missing from a wheel (the apps'
    Voilà template was, once)."""
    import fnmatch
    import subprocess

    patterns = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["repro"]
    tracked = subprocess.run(["git", "ls-files", "repro"], cwd=REPO, capture_output=True, text=True,
                             check=True).stdout.split()
    data = [p.removeprefix("repro/") for p in tracked if not p.endswith(".py")]
    assert data, "git ls-files found no data files under repro/"
    # setuptools' glob: "*" does not cross "/", as fnmatch's does; compare segment counts too
    missed = [p for p in data if not any(fnmatch.fnmatch(p, pat) and p.count("/") == pat.count("/")
                                         for pat in patterns)]
    assert not missed, f"not in package-data (a wheel would lack them): {missed}"


def test_citation_cff_names_the_project_and_both_papers():
    """CITATION.cff (Citation File Format 1.2.0) has its required keys and cites the two papers."""
    cff = yaml.safe_load((REPO / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0"
    for key in ("message", "title", "authors"):
        assert cff.get(key), key
    assert cff["version"] == tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    titles = [r["title"] for r in cff["references"]]
    assert titles == ["Reducing Blendshape Interference by Selected Motion Attenuation",
                      "Interactive Animation of Virtual Characters: Application to Virtual Kung-fu Fighting"]
    for ref in cff["references"]:
        assert ref["type"] and ref["authors"], ref["title"]
    assert [a["family-names"] for a in cff["references"][0]["authors"]] == ["Lewis", "Mooser", "Deng", "Neumann"]
    assert [a["family-names"] for a in cff["references"][1]["authors"]] == [
        "Pronost", "Li", "Geng", "Multon", "Kulpa", "Dumont"]


def test_binder_files_install_what_setup_installs():
    """Binder (repo2docker, not runnable here): apt.txt lists setup.sh's rendering libraries, postBuild
    is executable and installs the kernel configuration setup.sh installs, and environment.yml installs
    the project itself."""
    import os

    setup = (REPO / "scripts" / "setup.sh").read_text()
    rendering = re.search(r"for p in ([^;]+); do", setup).group(1).split()
    apt = (REPO / "apt.txt").read_text().split()
    assert apt == [p for p in rendering if not p.startswith("chromium")]
    post = REPO / "postBuild"
    assert os.access(post, os.X_OK)
    assert "scripts/ipython/ipython_kernel_config.py" in post.read_text()
    assert "scripts/ipython/ipython_kernel_config.py" in setup
    env = yaml.safe_load((REPO / "environment.yml").read_text())
    pip = next(d["pip"] for d in env["dependencies"] if isinstance(d, dict))
    assert "-e ." in pip


LOCK = REPO / "requirements" / "lock-py311-linux.txt"


def _locked() -> dict[str, tuple[str, list[str]]]:
    """``{name: (version, [sha256, ...])}`` of the lock file's requirements."""
    pins: dict[str, tuple[str, list[str]]] = {}
    text = LOCK.read_text().replace("\\\n", " ")
    for line in text.splitlines():
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        m = re.match(r"([A-Za-z0-9_.\-]+)==([^\s;]+)", line.strip())
        assert m, f"not an exact pin: {line.strip()[:80]}"
        pins[m.group(1).lower().replace("_", "-")] = (m.group(2), re.findall(r"--hash=sha256:([0-9a-f]{64})", line))
    return pins


def test_the_lock_pins_every_dependency_with_hashes():
    """Every package pyproject.toml names (runtime, dev extra, build backend) is pinned with ``==`` and at
    least one sha256 in the lock, as ``pip install --require-hashes`` needs; so is everything in it."""
    project = tomllib.loads((REPO / "pyproject.toml").read_text())
    named = {_name(r).replace("_", "-") for r in project["project"]["dependencies"]
             + project["project"]["optional-dependencies"]["dev"] + project["build-system"]["requires"]}
    pins = _locked()
    assert named - set(pins) == set(), f"named in pyproject.toml, not locked: {sorted(named - set(pins))}"
    unhashed = [n for n, (_, hashes) in pins.items() if not hashes]
    assert not unhashed, f"locked without a hash: {unhashed}"
    assert "repro" not in pins


def test_setup_installs_from_the_lock_unless_asked_for_the_newest():
    setup = (REPO / "scripts" / "setup.sh").read_text()
    assert f"LOCK={LOCK.relative_to(REPO)}" in setup
    # the lock hash-checked by uv (itself pinned and hash-checked), or by pip where uv cannot be installed
    assert "install -q --require-hashes -r requirements/uv.txt" in setup
    assert re.search(r'uv pip install --quiet --native-tls --compile-bytecode --python .venv/bin/python \\\s+'
                     r'--require-hashes -r "\$LOCK"; then', setup)
    assert 'install -q --require-hashes -r "$LOCK"' in setup
    assert "--no-deps --no-build-isolation -e ." in setup
    assert "REPRO_UNPINNED" in setup and "-e '.[dev]'" in setup


def test_the_installer_uv_is_pinned_with_hashes():
    """requirements/uv.txt: uv at one version, with a sha256 for (at least) both Linux wheels the lock is for."""
    text = (REPO / "requirements" / "uv.txt").read_text().replace("\\\n", " ")
    pins = [line.strip() for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    assert len(pins) == 1 and re.match(r"uv==\d+\.\d+\.\d+ ", pins[0]), pins
    assert len(re.findall(r"--hash=sha256:[0-9a-f]{64}", pins[0])) >= 2


def test_the_editable_install_is_a_plain_pth_file():
    """``package-dir = {"" = "."}`` makes setuptools' editable install a ``.pth`` file naming the checkout
    (its ``_StaticPth`` strategy), which emits no warning; without it setuptools picks its meta path finder,
    whose ``InformationOnly`` block pip >= 25 relays as a ``BuildBackendWarning`` on every set-up (issue 27,
    item 3: a newcomer sees only setup.sh's own lines)."""
    setuptools_cfg = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert setuptools_cfg["package-dir"] == {"": "."}


def test_the_environment_setup_installed_is_the_lock():
    """Where scripts/setup.sh installed the lock (its stamp says unpinned=0) and this is its .venv: every locked
    package at its locked version (a tool a developer adds later is not the set-up's: not checked)."""
    import importlib.metadata
    import sys

    stamp = REPO / ".venv" / ".repro-installed"
    if Path(sys.prefix).resolve() != (REPO / ".venv").resolve() or not stamp.is_file():
        pytest.skip("not the .venv scripts/setup.sh made")
    if not stamp.read_text().strip().endswith("unpinned=0"):
        pytest.skip("set up with REPRO_UNPINNED=1 (the newest versions, not the lock)")
    installed = {d.metadata["Name"].lower().replace("_", "-"): d.version for d in importlib.metadata.distributions()}
    wrong = {n: (v, installed.get(n)) for n, (v, _) in _locked().items() if installed.get(n) != v}
    assert not wrong, f"locked version vs installed: {wrong}"
