"""README.md says what works: its commands exist and run, as written, for a new user.

The fast tests check the README's text against the code (the first code block, the CI
command, every ``cwproc`` command and option named in a shell block, the links and
pictures). The slow test follows the README in a new virtual environment: it copies the
tracked files of the repository, installs cwproc from the copy, and runs the main-job line
and every block of the tour marked ``<!-- tested -->`` exactly as written (the blocks
not marked need the user's own files under ``/data/`` or take minutes). The environment
sees only the dependencies cwproc declares (``declared_only_sitecustomize.py``).
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import click
import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
CI_RUN = REPO / ".ci" / "run"

#: the two commands of a new user, the first code block of the README
MAIN_JOB = "pip install . && cwproc retrieve sample_data/ -c sample_data/site.toml -o out/"
TEST_LINE = 'pip install -e ".[test]" && python3 -m pytest -q -n auto -m "slow or not slow"'

#: marker of the README blocks that the slow test runs
TESTED = "<!-- tested -->"

#: largest picture committed under docs/images (bytes)
MAX_PNG_BYTES = 150_000

FENCE = re.compile(r"^```(?P<lang>[^\n`]*)\n(?P<body>.*?)^```\s*$", re.M | re.S)
LINK = re.compile(r"!?\[[^\]]*\]\((?P<target>[^)\s]+)\)")


@dataclass(frozen=True)
class Block:
    """A fenced code block of the README."""

    lang: str
    lines: tuple[str, ...]
    tested: bool
    line_number: int


def code_blocks(text: str) -> list[Block]:
    """Fenced code blocks of a Markdown text, with whether ``<!-- tested -->`` precedes them."""
    blocks = []
    for match in FENCE.finditer(text):
        before = text[: match.start()].rstrip().splitlines()
        tested = bool(before) and before[-1].strip() == TESTED
        blocks.append(
            Block(
                lang=match["lang"].strip(),
                lines=tuple(match["body"].splitlines()),
                tested=tested,
                line_number=text.count("\n", 0, match.start()) + 1,
            )
        )
    return blocks


def shell_commands(lines: tuple[str, ...]) -> list[str]:
    """Commands of a shell block: comment lines dropped, ``\\`` continuations joined."""
    commands: list[str] = []
    pending = ""
    for raw in lines:
        line = raw.rstrip()
        if not pending and (not line.strip() or line.lstrip().startswith("#")):
            continue
        if line.endswith("\\"):
            pending += line[:-1] + " "
            continue
        commands.append(pending + line)
        pending = ""
    if pending:
        commands.append(pending.rstrip())
    return commands


def readme_blocks() -> list[Block]:
    return code_blocks(README.read_text(encoding="utf-8"))


def bash_blocks() -> list[Block]:
    return [b for b in readme_blocks() if b.lang in ("bash", "sh", "shell")]


def cwproc_invocations(command: str) -> list[list[str]]:
    """The argument lists of every ``cwproc`` call in one shell command line."""
    lexer = shlex.shlex(command, posix=True, punctuation_chars=True)
    lexer.whitespace_split = True
    calls: list[list[str]] = []
    words: list[str] = []
    for token in [*lexer, ";"]:
        if token and set(token) <= set("();<>|&"):
            if words and words[0] == "cwproc":
                calls.append(words[1:])
            words = []
        else:
            words.append(token)
    return calls


# --------------------------------------------------------------------------------------
# fast: the README's text against the code
# --------------------------------------------------------------------------------------


def test_first_block_is_the_install_run_and_test_commands():
    first = readme_blocks()[0]
    assert first.lang == "bash"
    assert list(first.lines) == [MAIN_JOB, TEST_LINE]
    # the main job's input exists in the repository and holds Stream Line files
    assert sorted(p.name for p in (REPO / "sample_data" / "streamline").glob("*.hpl"))


def test_ci_runs_the_readme_test_command():
    readme_install, readme_test = (s.strip() for s in readme_blocks()[0].lines[1].split("&&"))
    lines = [
        line.strip()
        for line in CI_RUN.read_text(encoding="utf-8").splitlines()
        if line.strip() and not line.lstrip().startswith("#")
    ]
    runs = [line for line in lines if "pytest" in line]
    assert len(runs) == 1, f".ci/run should run pytest once, found {runs}"
    ci_install, ci_test = (s.strip() for s in runs[0].split("&&"))
    # CI runs exactly the README's command, slow statistical checks included
    assert ci_test == readme_test
    assert ci_test.endswith('-m "slow or not slow"')
    # both install the same target: the package with its test extras
    assert shlex.split(readme_install)[-1] == shlex.split(ci_install)[-1] == ".[test]"


def _resolve(args: list[str]):
    """The click command that ``cwproc args`` runs and the arguments left for it."""
    from cwproc.cli import main

    command, rest = main, list(args)
    while isinstance(command, click.Group) and rest and not rest[0].startswith("-"):
        sub = command.get_command(click.Context(command), rest[0])
        assert sub is not None, f"`cwproc {' '.join(args)}`: no command {rest[0]!r}"
        command, rest = sub, rest[1:]
    return command, rest


def test_every_cwproc_command_and_option_in_the_readme_exists():
    calls = [
        call
        for block in bash_blocks()
        for command in shell_commands(block.lines)
        for call in cwproc_invocations(command)
    ]
    assert len(calls) >= 15, "the tour names the commands of every section"
    named = set()
    for call in calls:
        command, rest = _resolve(call)
        assert not isinstance(command, click.Group), f"`cwproc {' '.join(call)}` is a group"
        named.add(command.name)
        options = {opt for p in command.params for opt in getattr(p, "opts", [])}
        for word in rest:
            if word.startswith("-") and word != "-":
                assert word.split("=")[0] in options, f"`cwproc {' '.join(call)}`: no {word}"
    from cwproc.cli import main

    # every command of the CLI appears in the tour
    ctx = click.Context(main)
    leaves = set()
    for name in main.list_commands(ctx):
        cmd = main.get_command(ctx, name)
        if isinstance(cmd, click.Group):
            sub_ctx = click.Context(cmd)
            leaves |= {cmd.get_command(sub_ctx, n).name for n in cmd.list_commands(sub_ctx)}
        else:
            leaves.add(cmd.name)
    assert leaves <= named


def test_links_and_pictures_of_the_readme_exist():
    text = README.read_text(encoding="utf-8")
    targets = [m["target"] for m in LINK.finditer(text) if "://" not in m["target"]]
    assert targets, "the README links to its documentation"
    for target in targets:
        assert (REPO / target.split("#")[0]).is_file(), f"README links to missing {target}"
    pictures = [t for t in targets if t.endswith(".png")]
    assert len(pictures) >= 4
    for target in pictures:
        data = (REPO / target).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{target} is not a PNG"
        assert 10_000 < len(data) < MAX_PNG_BYTES, f"{target}: {len(data)} bytes"


def test_images_script_makes_every_readme_picture():
    script = (REPO / "docs" / "make_images.sh").read_text(encoding="utf-8")
    text = README.read_text(encoding="utf-8")
    for target in re.findall(r"\]\((docs/images/[^)]+\.png)\)", text):
        assert f"-o {target}" in script, f"docs/make_images.sh does not make {target}"


def shown_output(first_line_prefix: str) -> list[str]:
    """Lines of the README's plain (output) block whose first line starts so."""
    shown = [
        list(b.lines)
        for b in readme_blocks()
        if b.lang == "" and b.lines and b.lines[0].startswith(first_line_prefix)
    ]
    assert len(shown) == 1, f"README shows {len(shown)} outputs starting {first_line_prefix!r}"
    return shown[0]


def test_info_output_shown_in_the_readme_is_what_cwproc_prints(monkeypatch):
    from click.testing import CliRunner

    from cwproc.cli import main

    (command,) = [
        c
        for b in bash_blocks()
        if b.tested
        for c in shell_commands(b.lines)
        if c.startswith("cwproc info")
    ]
    args = cwproc_invocations(command)[0]  # info FILE
    monkeypatch.chdir(REPO)
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    assert result.output.strip().splitlines() == shown_output(args[-1])


def test_main_job_output_shown_in_the_readme_is_what_cwproc_prints(tmp_path, monkeypatch):
    """Every line the README shows for the main job, notes included, in order, is what
    ``cwproc retrieve sample_data/ -c sample_data/site.toml -o out/`` prints (run in a
    folder holding the samples, so that the paths are the README's)."""
    from click.testing import CliRunner

    from cwproc.cli import main

    (args,) = cwproc_invocations(MAIN_JOB)
    (tmp_path / "sample_data").symlink_to(REPO / "sample_data")
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    shown = shown_output("note: ")
    assert shown[-3].startswith("wrote out/")
    assert result.output.strip().splitlines() == shown


def test_readme_epsilon_of_the_first_block_is_the_products(tmp_path):
    """The ranges of epsilon the README states for the first block of the sample."""
    from click.testing import CliRunner

    from cwproc.cli import main
    from cwproc.io.netcdf import read_product

    out = tmp_path / "out"
    scans, site = REPO / "sample_data" / "streamline", REPO / "sample_data" / "site.toml"
    args = ["retrieve", str(scans), "-c", str(site), "-o", str(out), "-q"]
    assert CliRunner().invoke(main, args).exit_code == 0
    (path,) = out.glob("*_turbulence.nc")
    eps = read_product(path)["epsilon"].isel(time=0).to_series()
    text = " ".join(README.read_text(encoding="utf-8").split())
    m = re.search(r"first block is (0\.\d+)–(0\.\d+) m² s-3 from 130 m up", text)
    assert m, "README no longer states the range of the first block"
    up = eps[eps.index >= 130].round(4)
    assert (float(m[1]), float(m[2])) == (up.min(), up.max())
    m = re.search(r"lower, (0\.\d+)–(0\.\d+), below 120 m", text)
    assert m, "README no longer states the range below 120 m"
    low = eps[eps.index < 120].round(4)
    assert (float(m[1]), float(m[2])) == (low.min(), low.max())


def acdd_report(path: Path, tmp_path: Path) -> dict:
    """The ACDD-1.3 report of the IOOS compliance checker for one NetCDF file."""
    from compliance_checker.runner import CheckSuite, ComplianceChecker

    CheckSuite.load_all_available_checkers()
    out = tmp_path / f"{path.stem}.acdd.json"
    ComplianceChecker.run_checker(
        os.fspath(path),
        ["acdd:1.3"],
        verbose=0,
        criteria="normal",
        output_filename=os.fspath(out),
        output_format="json",
    )
    return next(iter(json.loads(out.read_text()).values()))


@pytest.mark.slow
def test_output_table_of_the_readme_completes_the_acdd_attributes(tmp_path):
    """The README's [output] table fills every required and highly recommended ACDD
    global attribute; what the checker still misses are variables without a CF name."""
    import xarray as xr
    from click.testing import CliRunner

    from cwproc.cli import main
    from cwproc.metadata.products import VARIABLES

    (table,) = [b for b in readme_blocks() if b.lang == "toml" and b.lines[0] == "[output]"]
    preset = (REPO / "configs" / "streamline.toml").read_text(encoding="utf-8")
    config = tmp_path / "mysite.toml"
    config.write_text(preset + "\n" + "\n".join(table.lines) + "\n", encoding="utf-8")
    out = tmp_path / "out_site"
    sample = REPO / "sample_data" / "streamline"
    args = ["retrieve", str(sample), "-c", str(config), "-o", str(out), "-q"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    for product in sorted(out.glob("*.nc")):
        report = acdd_report(product, tmp_path)
        missing = [(c["name"], m) for c in report["high_priorities"] for m in c["msgs"]]
        for name, msg in missing:
            variable = re.fullmatch(r'variable "(\w+)" missing the following attributes:', name)
            assert variable and msg == "standard_name", f"{product.name}: {name} {msg}"
            assert VARIABLES[variable[1]].standard_name is None, variable[1]
        assert [m for c in report["medium_priorities"] for m in c["msgs"]] == []
        with xr.open_dataset(product) as ds:
            unset = sorted(k for k, v in ds.attrs.items() if v == "not specified")
            assert unset == ["creator_url", "publisher_url"], product.name
            assert float(ds["latitude"]) == pytest.approx(56.48)
            assert float(ds["longitude"]) == pytest.approx(85.10)


def cwproc_names() -> set[str]:
    """Public names of every cwproc module, configuration keys and product variables."""
    import dataclasses
    import importlib
    import pkgutil

    import cwproc
    from cwproc.config import Config
    from cwproc.metadata.products import VARIABLES

    names: set[str] = set(VARIABLES)
    for info in pkgutil.walk_packages(cwproc.__path__, "cwproc."):
        if info.name.endswith("__main__"):
            continue  # runs the command line when imported
        module = importlib.import_module(info.name)
        short = info.name.rsplit(".", 1)[-1]
        for attr in dir(module):
            if not attr.startswith("_"):
                names |= {attr, f"{short}.{attr}"}
    for section in dataclasses.fields(Config):
        value = getattr(Config(), section.name)
        if dataclasses.is_dataclass(value):
            names.add(f"[{section.name}]")
            names |= {f.name for f in dataclasses.fields(value)}
    return names


def test_physics_page_names_only_code_that_exists():
    """Every function, module, key or variable docs/physics.md names in backticks exists."""
    text = (REPO / "docs" / "physics.md").read_text(encoding="utf-8")
    names = cwproc_names()
    tokens = set(re.findall(r"`([^`\s]+)`", text))
    assert len(tokens) > 100
    for token in sorted(tokens):
        if token.startswith(("../", "real_data/")):
            continue  # the shared folder outside the repository
        if token.endswith((".py", "/")):
            assert (REPO / token).exists() or (REPO / "cwproc" / token).exists(), token
        else:
            assert token in names, f"docs/physics.md names `{token}`, which cwproc lacks"


def test_tested_blocks_reach_a_plot():
    commands = [c for b in bash_blocks() if b.tested for c in shell_commands(b.lines)]
    assert any(call[:1] == ["plot"] for c in commands for call in cwproc_invocations(c))


# --------------------------------------------------------------------------------------
# slow: a new user follows the README in a fresh virtual environment
# --------------------------------------------------------------------------------------


def tracked_files(repo: Path) -> list[str]:
    """Paths of the files git tracks in ``repo`` (skips the test when git cannot say)."""
    try:
        out = subprocess.run(
            ["git", "ls-files", "-z"], cwd=repo, capture_output=True, check=True, timeout=60
        ).stdout
    except (OSError, subprocess.CalledProcessError, subprocess.TimeoutExpired) as exc:
        pytest.skip(f"cannot list the tracked files with git: {exc}")
    return [p for p in out.decode().split("\0") if p]


def copy_tracked(repo: Path, dest: Path) -> None:
    """Copy the working-tree version of every tracked file (symlinks stay symlinks)."""
    for name in tracked_files(repo):
        src = repo / name
        if not src.exists() and not src.is_symlink():
            continue  # deleted in the working tree
        target = dest / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, target, follow_symlinks=False)


def tour_commands() -> list[str]:
    """The main-job line, then the commands of every tested block, in README order."""
    commands = [readme_blocks()[0].lines[0]]
    for block in bash_blocks()[1:]:
        if block.tested:
            commands += shell_commands(block.lines)
    assert any("cwproc plot" in c for c in commands), "no tested README block runs a plot"
    return commands


#: the environment's ``sitecustomize``: only the dependencies cwproc declares
DECLARED_ONLY = Path(__file__).with_name("declared_only_sitecustomize.py")


def venv_environment(venv: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env["VIRTUAL_ENV"] = str(venv)
    env["PATH"] = str(venv / "bin") + os.pathsep + env.get("PATH", "")
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    # no byte-compilation of the installed packages: saves a minute on a loaded machine,
    # and Python compiles what it imports anyway
    env["PIP_NO_COMPILE"] = "1"
    # `pip install .` builds and installs cwproc (build isolation kept: the build
    # requirements of pyproject.toml are installed as for a user) but not its
    # dependencies: the environment takes them from the site-packages of the tests'
    # interpreter, limited by declared_only_sitecustomize.py to what cwproc declares
    # (unpacking them again cost about 500 MB and most of the test's minute and a half)
    env["PIP_NO_DEPS"] = "1"
    env["MPLBACKEND"] = "Agg"
    return env


def declared_only_venv(venv: Path) -> None:
    """A virtual environment that sees the site-packages of the interpreter running the
    tests (a venv's or the system's), but of them only the distributions cwproc's
    metadata requires (``declared_only_sitecustomize.py``)."""
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300)
    (site_packages,) = (venv / "lib").glob("python3*/site-packages")
    outer = [p for p in sys.path if Path(p).name in ("site-packages", "dist-packages")]
    # site.addsitedir also runs their .pth files (editable installs), as Python would
    lines = [f"import site; site.addsitedir({p!r})" for p in outer]
    (site_packages / "zz_outer_site_packages.pth").write_text("\n".join(lines) + "\n")
    shutil.copy(DECLARED_ONLY, site_packages / "sitecustomize.py")


@pytest.mark.slow
def test_environment_sees_only_the_declared_dependencies(tmp_path):
    """The guard of the new user's environment refuses an installed module cwproc does not
    declare (pytest is installed here, no requirement of cwproc brings it) and lets the
    declared ones through, from the site-packages of the tests' interpreter."""
    venv = tmp_path / "venv"
    declared_only_venv(venv)
    env = venv_environment(venv)
    env["CWPROC_TEST_REFUSED_IMPORTS"] = str(tmp_path / "refused.txt")
    python = str(venv / "bin" / "python")
    # a stand-in for cwproc in the environment (its metadata only): the guard reads its
    # requirements
    (site_packages,) = (venv / "lib").glob("python3*/site-packages")
    info = site_packages / "cwproc-0.0.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: cwproc\nVersion: 0.0.0\nRequires-Dist: xarray\n"
        'Requires-Dist: pytest; extra == "test"\n',
        encoding="utf-8",
    )
    (info / "RECORD").write_text("cwproc-0.0.0.dist-info/METADATA,,\n", encoding="utf-8")
    probe = "import importlib.util as u; import xarray, numpy; print(u.find_spec('{}'))"
    ok = subprocess.run(
        [python, "-c", probe.format("pandas")], env=env, capture_output=True, text=True
    )
    assert ok.returncode == 0, ok.stderr  # xarray and what it requires (numpy, pandas)
    assert "ModuleSpec(name='pandas'" in ok.stdout
    refused = subprocess.run(
        [python, "-c", "import pytest"], env=env, capture_output=True, text=True
    )
    assert refused.returncode == 1
    assert "No module named 'pytest'" in refused.stderr
    refused_names = (tmp_path / "refused.txt").read_text().split()
    assert "pytest" in refused_names
    assert not {"xarray", "numpy", "pandas"} & set(refused_names)


@pytest.mark.slow
def test_new_user_follows_the_readme(tmp_path):
    copy = tmp_path / "cwproc"
    copy_tracked(REPO, copy)
    venv = tmp_path / "venv"
    declared_only_venv(venv)
    env = venv_environment(venv)
    refused = tmp_path / "refused_imports.txt"
    env["CWPROC_TEST_REFUSED_IMPORTS"] = str(refused)

    commands = tour_commands()
    for command in commands:
        result = subprocess.run(
            ["bash", "-c", command],
            cwd=copy,
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert result.returncode == 0, (
            f"README command failed (exit {result.returncode}): {command}\n"
            f"--- stdout\n{result.stdout[-3000:]}\n--- stderr\n{result.stderr[-3000:]}"
        )
        if command == MAIN_JOB:
            # what the README shows the main job printing
            printed = (result.stdout + result.stderr).splitlines()  # notes go to stderr
            for line in shown_output("note: "):
                assert line in printed, f"main job did not print {line!r}"
    # the commands ran the virtual environment's cwproc, not another installation
    assert shutil.which("cwproc", path=env["PATH"]) == str(venv / "bin" / "cwproc")
    where = subprocess.run(
        ["python", "-c", "import cwproc; print(cwproc.__file__)"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    assert Path(where).resolve().is_relative_to(venv.resolve()), where
    # what the commands tried to import but cwproc does not declare (the optional
    # imports of its dependencies, e.g. xarray's of dask, find nothing, as in an
    # environment where only cwproc's requirements were installed)
    print("refused imports:", sorted(set(refused.read_text().split())) if refused.exists() else [])

    import xarray as xr

    truth = json.loads((REPO / "sample_data" / "streamline_truth.json").read_text())
    (wind_path,) = sorted((copy / "out").glob("*_wind.nc"))
    (turb_path,) = sorted((copy / "out").glob("*_turbulence.nc"))
    with xr.open_dataset(wind_path) as wind:
        speed = wind["wind_speed"].values
        direction = wind["wind_direction"].values
        # the sample wind: 6 m/s from 240 deg; turbulence (sigma_V ~ 1.3 m/s) scatters
        # single-scan values, the medians over all scans and heights agree within 10 %
        assert np.isfinite(speed).mean() > 0.9
        assert np.nanmedian(speed) == pytest.approx(truth["wind_speed_m_s"], rel=0.10)
        assert np.nanmedian(direction) == pytest.approx(truth["wind_direction_deg"], abs=10)
    with xr.open_dataset(turb_path) as turb:
        eps = turb["epsilon"].values
        # epsilon of the sample series (0.01 m2 s-3) within a factor 2 (median)
        assert np.isfinite(eps).mean() > 0.5
        assert 0.5 < np.nanmedian(eps) / truth["epsilon_m2_s3"] < 2.0

    import matplotlib.image as mpimg

    pngs = [copy / m for c in commands if "cwproc plot" in c for m in re.findall(r"-o\s+(\S+)", c)]
    assert pngs
    for png in pngs:
        image = mpimg.imread(png)
        assert png.stat().st_size > 10_000
        assert image.shape[0] >= 300 and image.shape[1] >= 400
        # drawn, not blank: many distinct pixel values
        assert np.unique(image.reshape(-1, image.shape[-1]), axis=0).shape[0] > 50
